#include "st/report/fits_stack.hpp"

#include "st/common/error.hpp"
#include "st/io/fits_writer.hpp"
#include "st/io/wcs.hpp"

namespace st::report {

FitsHeader wcsCardsAtTRef(const Wcs& wcs, Velocity skyRate, double mappingEpochOffsetS) {
  FitsHeader h = wcs.toHeader();
  const double shift[2] = {skyRate.vx * mappingEpochOffsetS, skyRate.vy * mappingEpochOffsetS};
  for (int i = 0; i < 2; ++i) {
    const std::string key = "CRPIX" + std::to_string(i + 1);
    const auto v = h.getDouble(key);
    if (!v) throw InputError("WCS has no " + key + " card to move to t_ref");
    const FitsCard* card = h.find(key);
    h.setNumber(key, *v - shift[i], card != nullptr ? card->comment : std::string{});
  }
  return h;
}

void writeStackFits(const std::string& path, const Image& stack, const StackProvenance& p, const Wcs* wcs,
                    double mappingEpochOffsetS) {
  FitsHeader params;
  params.setNumber("STVX", p.velocity.vx, "stack velocity x [px/s]");
  params.setNumber("STVY", p.velocity.vy, "stack velocity y [px/s]");
  params.setNumber("SKYVX", p.skyRate.vx, "sky rate x [px/s]");
  params.setNumber("SKYVY", p.skyRate.vy, "sky rate y [px/s]");
  params.setNumber("TREFMJD", p.tRefMjd, "epoch of the pixel positions, MJD (UTC)");
  params.setNumber("NFRAMES", static_cast<double>(p.frames), "frames stacked");
  params.setString("STMODE", p.mode, "stack mode");
  if (wcs != nullptr) params.setNumber("WCSEPOCH", p.tRefMjd, "MJD (UTC) the WCS maps pixel positions at");
  FitsHeader h = io::provenanceCards(p.what, params);
  for (const auto& in : p.inputs)
    h.cards.push_back(FitsCard{"HISTORY", "", "input " + in, false});
  if (wcs != nullptr) {
    for (const auto& c : wcsCardsAtTRef(*wcs, p.skyRate, mappingEpochOffsetS).cards)
      h.cards.push_back(c);
  }
  io::writeImage(path, stack, h);
}

}  // namespace st::report
