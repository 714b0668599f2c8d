#include "st/report/fits_stack.hpp"

#include <fitsio.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "st/common/error.hpp"
#include "st/io/fits_writer.hpp"
#include "st/io/wcs.hpp"

namespace st::report {

FitsHeader wcsCardsAtTRef(const Wcs& wcs, Velocity skyRate, double mappingEpochOffsetS,
                          PixelOffset mappingFrameOffset) {
  FitsHeader h = wcs.toHeader();
  const double shift[2] = {skyRate.vx * mappingEpochOffsetS + mappingFrameOffset.x,
                           skyRate.vy * mappingEpochOffsetS + mappingFrameOffset.y};
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

/// The median (the mean of the two middle values for an even count); 0 for none.
double median(std::vector<float> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2 == 1) return *mid;
  const double upper = *mid;
  return 0.5 * (upper + *std::max_element(v.begin(), mid));
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
  const int w = sum.width, h = sum.height;
  if (box <= 0) box = std::max(16, std::min(w, h) / 8);
  Image mean(w, h, std::numeric_limits<float>::quiet_NaN());
  std::vector<float> all;
  for (std::size_t i = 0; i < sum.size(); ++i) {
    if (coverage[i] == 0 || !std::isfinite(sum.pixels[i])) continue;
    mean.pixels[i] = sum.pixels[i] / coverage[i];
    all.push_back(mean.pixels[i]);
  }
  const double fallback = median(all);
  // A mesh of box x box cells, each its median (robust to the sources), interpolated bilinearly between the
  // cells' centres and extrapolated linearly beyond them: a gradient across the frame is removed up to the
  // edges (SExtractor's background mesh, without the filtering).
  const int nx = (w + box - 1) / box, ny = (h + box - 1) / box;
  std::vector<double> cx(static_cast<std::size_t>(nx)), cy(static_cast<std::size_t>(ny));
  for (int i = 0; i < nx; ++i)
    cx[static_cast<std::size_t>(i)] = 0.5 * (i * box + std::min(w, (i + 1) * box) - 1);
  for (int j = 0; j < ny; ++j)
    cy[static_cast<std::size_t>(j)] = 0.5 * (j * box + std::min(h, (j + 1) * box) - 1);
  std::vector<double> mesh(static_cast<std::size_t>(nx) * ny, fallback);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      std::vector<float> v;
      for (int y = j * box; y < std::min(h, (j + 1) * box); ++y)
        for (int x = i * box; x < std::min(w, (i + 1) * box); ++x)
          if (const float m = mean.at(x, y); std::isfinite(m)) v.push_back(m);
      const std::size_t area = static_cast<std::size_t>(std::min(w, (i + 1) * box) - i * box) *
                               static_cast<std::size_t>(std::min(h, (j + 1) * box) - j * box);
      if (v.size() * 4 >= area) mesh[static_cast<std::size_t>(j) * nx + i] = median(v);
    }
  // Segment and weight of `x` among the centres `c` (linear beyond the ends).
  auto locate = [](const std::vector<double>& c, double x) {
    if (c.size() < 2) return std::pair<std::size_t, double>{0, 0.0};
    std::size_t k = 0;
    while (k + 2 < c.size() && x > c[k + 1])
      ++k;
    return std::pair<std::size_t, double>{k, (x - c[k]) / (c[k + 1] - c[k])};
  };
  Image out(w, h, std::numeric_limits<float>::quiet_NaN());
  for (int y = 0; y < h; ++y) {
    const auto [j, ty] = locate(cy, y);
    const std::size_t j1 = ny > 1 ? j + 1 : j;
    for (int x = 0; x < w; ++x) {
      const float m = mean.at(x, y);
      if (!std::isfinite(m)) continue;
      const auto [i, tx] = locate(cx, x);
      const std::size_t i1 = nx > 1 ? i + 1 : i;
      auto at = [&](std::size_t a, std::size_t b) { return mesh[b * static_cast<std::size_t>(nx) + a]; };
      const double bg = (1 - ty) * ((1 - tx) * at(i, j) + tx * at(i1, j)) + ty * ((1 - tx) * at(i, j1) + tx * at(i1, j1));
      out.at(x, y) = static_cast<float>(m - bg);
    }
  }
  return out;
}

void writeStackFits(const std::string& path, const Image& stack, const StackProvenance& p, const Wcs* wcs,
                    double mappingEpochOffsetS, const std::vector<std::uint16_t>* coverage,
                    PixelOffset mappingFrameOffset) {
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
    for (const auto& c : wcsCardsAtTRef(*wcs, p.skyRate, mappingEpochOffsetS, mappingFrameOffset).cards)
      h.cards.push_back(c);
  }
  io::writeImage(path, stack, h);
  if (coverage != nullptr) appendCoverage(path, stack.width, stack.height, *coverage);
}

}  // namespace st::report
