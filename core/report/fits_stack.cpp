#include "st/report/fits_stack.hpp"

#include <fitsio.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "st/common/error.hpp"
#include "st/io/fits_writer.hpp"
#include "st/io/wcs.hpp"
#include "st/stats/background.hpp"

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

namespace {

double median(std::vector<float> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

/// Appends the coverage map as an image extension "COVERAGE".
void appendCoverage(const std::string& path, int width, int height, const std::vector<std::uint16_t>& coverage) {
  int status = 0;
  fitsfile* f = nullptr;
  auto fail = [&](const char* what) {
    char text[FLEN_STATUS] = {};
    fits_get_errstatus(status, text);
    int ignored = 0;
    if (f) fits_close_file(f, &ignored);
    throw FitsError("'" + path + "': " + what + " (HDU COVERAGE): " + text);
  };
  if (fits_open_file(&f, path.c_str(), READWRITE, &status)) fail("cannot reopen to add the coverage");
  long naxes[2] = {width, height};
  if (fits_create_img(f, USHORT_IMG, 2, naxes, &status)) fail("cannot create the coverage image");
  char extname[] = "COVERAGE", bunit[] = "frames";
  fits_update_key(f, TSTRING, "EXTNAME", extname, "frames that contributed to each pixel", &status);
  fits_update_key(f, TSTRING, "BUNIT", bunit, nullptr, &status);
  std::vector<std::uint16_t> data(coverage);
  fits_write_img(f, TUSHORT, 1, static_cast<LONGLONG>(data.size()), data.data(), &status);
  if (status) fail("cannot write the coverage");
  if (fits_close_file(f, &status)) {
    f = nullptr;
    fail("cannot close");
  }
}

}  // namespace

Image backgroundSubtractedMean(const Image& sum, const std::vector<std::uint16_t>& coverage, int box) {
  if (coverage.size() != sum.size()) throw InputError("stack and coverage sizes differ");
  const float nan = std::numeric_limits<float>::quiet_NaN();
  if (box <= 0) box = std::max(15, std::min(sum.width, sum.height) / 8);
  if (box % 2 == 0) ++box;
  Image mean(sum.width, sum.height, 0.0f);
  std::vector<std::uint8_t> valid(sum.size(), 0);
  std::vector<float> values;
  for (std::size_t i = 0; i < sum.size(); ++i) {
    if (coverage[i] == 0 || !std::isfinite(sum.pixels[i])) continue;
    mean.pixels[i] = sum.pixels[i] / coverage[i];
    valid[i] = 1;
    values.push_back(mean.pixels[i]);
  }
  const double fallback = median(values);
  const Image first = stats::boxSmooth(mean, box, valid);
  std::vector<float> residuals;
  for (std::size_t i = 0; i < sum.size(); ++i)
    if (valid[i]) residuals.push_back(std::abs(mean.pixels[i] - first.pixels[i]));
  const double sigma = 1.4826 * median(residuals);
  std::vector<std::uint8_t> quiet(sum.size(), 0);
  Image indicator(sum.width, sum.height, 0.0f);
  for (std::size_t i = 0; i < sum.size(); ++i) {
    quiet[i] = valid[i] && std::abs(mean.pixels[i] - first.pixels[i]) <= 3.0 * sigma ? 1 : 0;
    indicator.pixels[i] = quiet[i];
  }
  const Image background = stats::boxSmooth(mean, box, quiet);
  const Image weight = stats::boxSmooth(indicator, box);
  Image out(sum.width, sum.height, nan);
  for (std::size_t i = 0; i < sum.size(); ++i) {
    if (!valid[i]) continue;
    const double bg = weight.pixels[i] > 0.0f ? background.pixels[i] : fallback;
    out.pixels[i] = static_cast<float>(mean.pixels[i] - bg);
  }
  return out;
}

void writeStackFits(const std::string& path, const Image& stack, const StackProvenance& p, const Wcs* wcs,
                    double mappingEpochOffsetS, const std::vector<std::uint16_t>* coverage) {
  FitsHeader params;
  params.setNumber("STVX", p.velocity.vx, "stack velocity x [px/s]");
  params.setNumber("STVY", p.velocity.vy, "stack velocity y [px/s]");
  params.setNumber("SKYVX", p.skyRate.vx, "sky rate x [px/s]");
  params.setNumber("SKYVY", p.skyRate.vy, "sky rate y [px/s]");
  params.setNumber("TREFMJD", p.tRefMjd, "epoch of the pixel positions, MJD (UTC)");
  params.setNumber("NFRAMES", static_cast<double>(p.frames), "frames stacked");
  params.setString("STMODE", p.mode, "stack mode");
  if (wcs != nullptr) params.setNumber("WCSEPOCH", p.tRefMjd, "MJD (UTC) the WCS maps pixel positions at");
  if (!p.bunit.empty()) params.setString("BUNIT", p.bunit, p.bunitComment);
  FitsHeader h = io::provenanceCards(p.what, params);
  for (const auto& in : p.inputs)
    h.cards.push_back(FitsCard{"HISTORY", "", "input " + in, false});
  if (wcs != nullptr) {
    for (const auto& c : wcsCardsAtTRef(*wcs, p.skyRate, mappingEpochOffsetS).cards)
      h.cards.push_back(c);
  }
  io::writeImage(path, stack, h);
  if (coverage != nullptr) appendCoverage(path, stack.width, stack.height, *coverage);
}

}  // namespace st::report
