#include "st/calib/calibration.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <string>

#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/common/prefault.hpp"
#include "st/io/wcs.hpp"
#include "st/stats/sigma_clip.hpp"

namespace st::calib {
namespace {

std::string sizeText(int w, int h) {
  return std::to_string(w) + "x" + std::to_string(h);
}

std::string fileOf(const FrameCube& c) {
  return c.info().empty() || c.info().front().file.empty() ? std::string("(in memory)")
                                                           : c.info().front().file;
}

float medianOf(std::vector<float>& v) {
  if (v.empty()) return 0.0f;
  const std::size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + m, v.end());
  if (v.size() % 2) return v[m];
  const float hi = v[m];
  return 0.5f * (hi + *std::max_element(v.begin(), v.begin() + m));
}

// Per-pixel median of value(n, i) over n, for i in [0, np).
Image combineMedian(int w, int h, std::size_t frames,
                    const std::function<float(std::size_t, std::size_t)>& value, CancelToken& cancel) {
  Image out(w, h);
  parallelFor(static_cast<std::size_t>(h), 8, [&](std::size_t y0, std::size_t y1) {
    std::vector<float> s;
    for (std::size_t y = y0; y < y1; ++y) {
      cancel.throwIfCancelled();
      for (int x = 0; x < w; ++x) {
        const std::size_t i = y * w + x;
        s.clear();
        for (std::size_t n = 0; n < frames; ++n) {
          const float v = value(n, i);
          if (std::isfinite(v)) s.push_back(v);
        }
        out.pixels[i] = medianOf(s);
      }
    }
  });
  return out;
}

float overscanLevel(const float* frame, int width, const Section& s) {
  std::vector<float> v;
  v.reserve(static_cast<std::size_t>(s.width) * s.height);
  for (int y = s.y0; y < s.y0 + s.height; ++y)
    for (int x = s.x0; x < s.x0 + s.width; ++x)
      v.push_back(frame[static_cast<std::size_t>(y) * width + x]);
  return medianOf(v);
}

// The section to use for `key`: the one given in params (which must fit), else the header's, made to fit
// the frames (clipped or ignored, with a warning). A malformed header section is ignored with a warning.
std::optional<Section> sectionFrom(const std::optional<Section>& given, const FrameCube& cube,
                                   const char* key, const CalibParams& params,
                                   std::vector<std::string>& warnings) {
  const int w = cube.width(), h = cube.height();
  if (given) {
    checkSectionInside(*given, w, h, key);
    return given;
  }
  if (!params.useHeaderSections) return std::nullopt;
  std::optional<Section> s;
  try {
    s = io::sectionFromHeader(cube.header, key);
  } catch (const InputError& e) {
    warnings.push_back(fileOf(cube) + ": " + e.what() + "; ignored");
    return std::nullopt;
  }
  if (!s) return std::nullopt;
  return fitSectionToFrame(*s, w, h, key, fileOf(cube), warnings);
}

// The trim region: TRIMSEC, else DATASEC (cameras that write only the data section).
std::optional<Section> trimFrom(const FrameCube& cube, const CalibParams& params,
                                std::vector<std::string>& warnings) {
  std::optional<Section> s = sectionFrom(params.trimSec, cube, "TRIMSEC", params, warnings);
  const auto text = cube.header.getString("TRIMSEC");
  const bool noTrimsec = !text || text->find_first_not_of(" \t") == std::string::npos;
  if (!s && !params.trimSec && params.useHeaderSections && noTrimsec) {
    s = sectionFrom(std::nullopt, cube, "DATASEC", params, warnings);
  }
  return s;
}

void checkMatches(const FrameCube& calib, const FrameCube& science, const char* what) {
  if (calib.empty()) return;
  if (calib.width() != science.width() || calib.height() != science.height()) {
    throw InputError(std::string(what) + " frame " + fileOf(calib) + " is " +
                     sizeText(calib.width(), calib.height()) + " but the science frames (" + fileOf(science) +
                     ") are " + sizeText(science.width(), science.height()));
  }
  const std::string bc = binningOf(calib.header), bs = binningOf(science.header);
  if (!bc.empty() && !bs.empty() && bc != bs) {
    throw InputError(std::string(what) + " frame " + fileOf(calib) + " has binning " + bc +
                     " but the science frames (" + fileOf(science) + ") have binning " + bs);
  }
}

std::vector<float> overscans(const FrameCube& c, const std::optional<Section>& s) {
  std::vector<float> out(c.frameCount(), 0.0f);
  if (!s) return out;
  for (std::size_t n = 0; n < c.frameCount(); ++n)
    out[n] = overscanLevel(c.frame(n), c.width(), *s);
  return out;
}

// Outliers of a master (hot pixels): one-sided clip over the trim region, then > mean + k sigma.
std::size_t markHot(const Image& img, const std::optional<Section>& region, double k,
                    std::vector<std::uint8_t>& bad) {
  const Section r = region.value_or(Section{0, 0, img.width, img.height});
  std::vector<float> v;
  for (int y = r.y0; y < r.y0 + r.height; ++y)
    for (int x = r.x0; x < r.x0 + r.width; ++x)
      v.push_back(img.at(x, y));
  const stats::ClipStats c = stats::sigmaClipSymmetric(v.data(), v.size(), 5.0);
  const double thr = c.mean + k * std::max(c.sigma, 1e-6);
  std::size_t count = 0;
  for (int y = r.y0; y < r.y0 + r.height; ++y)
    for (int x = r.x0; x < r.x0 + r.width; ++x)
      if (img.at(x, y) > thr && !bad[static_cast<std::size_t>(y) * img.width + x]) {
        bad[static_cast<std::size_t>(y) * img.width + x] = 1;
        ++count;
      }
  return count;
}

}  // namespace

std::string binningOf(const FitsHeader& header) {
  if (auto s = header.getString("CCDSUM")) return *s;
  const auto bx = header.getDouble("XBINNING"), by = header.getDouble("YBINNING");
  if (bx && by) return std::to_string(static_cast<int>(*bx)) + " " + std::to_string(static_cast<int>(*by));
  if (auto s = header.getString("BINNING")) return *s;
  return {};
}

Image medianCombine(const FrameCube& cube, CancelToken& cancel) {
  const auto& mask = cube.mask();
  const std::size_t np = cube.framePixels();
  return combineMedian(
      cube.width(), cube.height(), cube.frameCount(),
      [&](std::size_t n, std::size_t i) {
        if (!mask.empty() && mask[n * np + i]) return std::numeric_limits<float>::quiet_NaN();
        return cube.frame(n)[i];
      },
      cancel);
}

MasterCalibration buildMasters(const FrameCube& bias, const FrameCube& dark, const FrameCube& flat,
                               const FrameCube& science, const CalibParams& params, ProgressSink& progress,
                               CancelToken& cancel) {
  MasterCalibration m;
  if (science.empty()) throw InputError("calibration: no science frames to calibrate");
  checkMatches(bias, science, "bias");
  checkMatches(dark, science, "dark");
  checkMatches(flat, science, "flat");
  if (bias.empty() && (!dark.empty() || !flat.empty())) {
    throw InputError("calibration: dark or flat frames were given without bias frames");
  }
  m.width = science.width();
  m.height = science.height();
  const int w = m.width, h = m.height;
  if (params.subtractOverscan)
    m.biasSec = sectionFrom(params.biasSec, bias.empty() ? science : bias, "BIASSEC", params, m.warnings);
  m.trimSec = trimFrom(science, params, m.warnings);
  if (bias.empty()) return m;
  m.binning = binningOf(bias.header);
  const std::size_t np = science.framePixels();
  m.bad.assign(np, 0);

  progress.report(0.0, "master bias");
  const auto osBias = overscans(bias, m.biasSec);
  m.bias = combineMedian(
      w, h, bias.frameCount(), [&](std::size_t n, std::size_t i) { return bias.frame(n)[i] - osBias[n]; },
      cancel);
  if (!dark.empty()) {
    progress.report(0.3, "master dark");
    const auto osDark = overscans(dark, m.biasSec);
    for (std::size_t n = 0; n < dark.frameCount(); ++n) {
      if (!(dark.info()[n].exposureS > 0.0)) {
        throw InputError("dark frame " + dark.info()[n].file + " has no positive exposure time (EXPTIME)");
      }
    }
    m.darkPerS = combineMedian(
        w, h, dark.frameCount(),
        [&](std::size_t n, std::size_t i) {
          return static_cast<float>((dark.frame(n)[i] - osDark[n] - m.bias.pixels[i]) /
                                    dark.info()[n].exposureS);
        },
        cancel);
    m.hotPixels = markHot(m.darkPerS, m.trimSec, params.hotSigma, m.bad);
  } else {
    m.hotPixels = markHot(m.bias, m.trimSec, params.hotSigma, m.bad);
  }
  if (!flat.empty()) {
    progress.report(0.6, "master flat");
    const auto osFlat = overscans(flat, m.biasSec);
    const Section region = m.trimSec.value_or(Section{0, 0, w, h});
    // Each flat is normalised by its own median first: twilight flats differ in level.
    std::vector<double> norm(flat.frameCount());
    auto corrected = [&](std::size_t n, std::size_t i) {
      double v = flat.frame(n)[i] - osFlat[n] - m.bias.pixels[i];
      if (!m.darkPerS.empty()) v -= m.darkPerS.pixels[i] * flat.info()[n].exposureS;
      return v;
    };
    for (std::size_t n = 0; n < flat.frameCount(); ++n) {
      std::vector<float> v;
      for (int y = region.y0; y < region.y0 + region.height; ++y)
        for (int x = region.x0; x < region.x0 + region.width; ++x)
          v.push_back(static_cast<float>(corrected(n, static_cast<std::size_t>(y) * w + x)));
      const stats::ClipStats spread = stats::sigmaClipSymmetric(v.data(), v.size(), 5.0);
      norm[n] = medianOf(v);
      // A flat must stand well above its own pixel-to-pixel scatter; a bias-like frame does not.
      if (!(norm[n] > 5.0 * spread.sigma) || !(norm[n] > 0.0)) {
        throw InputError("flat frame " + flat.info()[n].file + " has a median of " + std::to_string(norm[n]) +
                         " counts after bias subtraction (scatter " + std::to_string(spread.sigma) +
                         "): not a usable flat");
      }
    }
    m.flat = combineMedian(
        w, h, flat.frameCount(),
        [&](std::size_t n, std::size_t i) { return static_cast<float>(corrected(n, i) / norm[n]); }, cancel);
    std::vector<float> v;
    for (int y = region.y0; y < region.y0 + region.height; ++y)
      for (int x = region.x0; x < region.x0 + region.width; ++x)
        v.push_back(m.flat.at(x, y));
    const double med = medianOf(v);
    if (!(med > 0.0)) throw InputError("master flat from " + fileOf(flat) + " has no positive median");
    for (std::size_t i = 0; i < np; ++i) {
      float& f = m.flat.pixels[i];
      const int x = static_cast<int>(i % w), y = static_cast<int>(i / w);
      const bool inside =
          x >= region.x0 && y >= region.y0 && x < region.x0 + region.width && y < region.y0 + region.height;
      f = inside ? static_cast<float>(f / med) : 1.0f;  // outside TRIMSEC (overscan) it is trimmed away
      if (!std::isfinite(f) || f <= 0.0f) {
        ++m.flatNonPositive;
        m.bad[i] = 1;
        f = 1.0f;
      } else if (f < params.flatLow || f > params.flatHigh) {
        ++m.flatOutliers;
        m.bad[i] = 1;
        f = 1.0f;
      }
    }
  }
  progress.report(1.0, "masters");
  return m;
}

namespace {

// Compacts the cube to `s` in place (the pixel and mask buffers are reused, never duplicated).
void trimInPlace(FrameCube& cube, const Section& s) {
  const int w = cube.width();
  const std::size_t np = cube.framePixels();
  auto compact = [&](auto& buf) {
    std::size_t dst = 0;
    for (std::size_t n = 0; n < cube.frameCount(); ++n)
      for (int y = s.y0; y < s.y0 + s.height; ++y) {
        const std::size_t src = n * np + static_cast<std::size_t>(y) * w + s.x0;
        std::copy(buf.begin() + src, buf.begin() + src + s.width, buf.begin() + dst);  // dst <= src
        dst += s.width;
      }
    buf.resize(dst);
  };
  compact(cube.pixels());
  if (!cube.mask().empty()) compact(cube.mask());
  FrameCube out(s.width, s.height, 0);
  out.pixels() = std::move(cube.pixels());
  out.mask() = std::move(cube.mask());
  out.info() = std::move(cube.info());
  out.header = std::move(cube.header);
  const bool hadWcs = cube.wcs != nullptr;
  out.plateScaleArcsecPerPx = cube.plateScaleArcsecPerPx;
  out.warnings = std::move(cube.warnings);
  // 0-based trim offset moves the reference pixel of a WCS by the same amount.
  for (const char* k : {"CRPIX1", "CRPIX2"}) {
    if (auto v = out.header.getDouble(k)) out.header.setNumber(k, *v - (k[5] == '1' ? s.x0 : s.y0));
  }
  out.header.erase("TRIMSEC");
  out.header.erase("BIASSEC");
  out.header.erase("DATASEC");
  // The WCS is re-read from the shifted cards so that it refers to the trimmed pixel grid.
  if (hadWcs) out.wcs = Wcs::fromHeader(out.header, &out.warnings);
  cube = std::move(out);
}

}  // namespace

std::optional<Section> trimRegion(const FitsHeader& header, int width, int height, const std::string& file,
                                  const CalibParams& params, std::vector<std::string>& warnings) {
  if (!params.trim) return std::nullopt;
  FrameCube frame(width, height, 1);  // the sections are read from a cube's header and size
  frame.header = header;
  frame.info()[0].file = file;
  std::optional<Section> s = trimFrom(frame, params, warnings);
  if (s && s->x0 == 0 && s->y0 == 0 && s->width == width && s->height == height) return std::nullopt;
  return s;
}

MasterCalibration cropMasters(const MasterCalibration& m, const Section& region) {
  if (region.x0 < 0 || region.y0 < 0 || region.width <= 0 || region.height <= 0 ||
      region.x0 + region.width > m.width || region.y0 + region.height > m.height)
    throw InputError("calibration masters of " + sizeText(m.width, m.height) + " cannot be cropped to " +
                     sizeText(region.width, region.height) + " at (" + std::to_string(region.x0) + ", " +
                     std::to_string(region.y0) + ")");
  MasterCalibration c = m;
  c.width = region.width;
  c.height = region.height;
  const auto cropImage = [&](const Image& in) {
    if (in.empty()) return Image();
    Image out(region.width, region.height);
    for (int y = 0; y < region.height; ++y)
      std::copy_n(in.pixels.begin() + static_cast<std::ptrdiff_t>(y + region.y0) * m.width + region.x0,
                  region.width, out.pixels.begin() + static_cast<std::ptrdiff_t>(y) * region.width);
    return out;
  };
  c.bias = cropImage(m.bias);
  c.darkPerS = cropImage(m.darkPerS);
  c.flat = cropImage(m.flat);
  if (!m.bad.empty()) {
    c.bad.assign(static_cast<std::size_t>(region.width) * static_cast<std::size_t>(region.height), 0);
    for (int y = 0; y < region.height; ++y)
      std::copy_n(m.bad.begin() + static_cast<std::ptrdiff_t>(y + region.y0) * m.width + region.x0, region.width,
                  c.bad.begin() + static_cast<std::ptrdiff_t>(y) * region.width);
  }
  // The sections moved into the region and clipped to it (none when nothing is left).
  const auto cropSection = [&](const std::optional<Section>& s) -> std::optional<Section> {
    if (!s) return std::nullopt;
    const int x0 = std::max(s->x0, region.x0), y0 = std::max(s->y0, region.y0);
    const int x1 = std::min(s->x0 + s->width, region.x0 + region.width);
    const int y1 = std::min(s->y0 + s->height, region.y0 + region.height);
    if (x1 <= x0 || y1 <= y0) return std::nullopt;
    return Section{x0 - region.x0, y0 - region.y0, x1 - x0, y1 - y0};
  };
  c.biasSec = cropSection(m.biasSec);
  c.trimSec = cropSection(m.trimSec);
  return c;
}

CalibrationPlan planCalibration(const FrameCube& cube, const MasterCalibration& masters,
                                const CalibParams& params) {
  CalibrationPlan plan;
  CalibrationReport& rep = plan.report;
  if (cube.empty()) throw InputError("calibration: the frame cube has no frames");
  const int w = cube.width(), h = cube.height();
  if (!masters.bias.empty() && (masters.width != w || masters.height != h)) {
    throw InputError("calibration masters are " + sizeText(masters.width, masters.height) +
                     " but the frames (" + fileOf(cube) + ") are " + sizeText(w, h));
  }
  std::optional<Section> biasSec = masters.bias.empty() ? std::nullopt : masters.biasSec;
  std::optional<Section> trimSec = masters.bias.empty() ? std::nullopt : masters.trimSec;
  if (masters.bias.empty()) {
    if (params.subtractOverscan) biasSec = sectionFrom(params.biasSec, cube, "BIASSEC", params, rep.warnings);
    trimSec = trimFrom(cube, params, rep.warnings);
  }
  const std::size_t nf = cube.frameCount();
  plan.overscan.assign(nf, 0.0f);
  plan.darkSeconds.resize(nf);
  for (std::size_t n = 0; n < nf; ++n)
    plan.darkSeconds[n] = static_cast<float>(cube.info()[n].exposureS);
  if (biasSec) {
    parallelFor(nf, 16, [&](std::size_t n0, std::size_t n1) {
      for (std::size_t n = n0; n < n1; ++n)
        plan.overscan[n] = overscanLevel(cube.frame(n), w, *biasSec);
    });
    rep.overscanLevel = plan.overscan;
  }
  if (!masters.bias.empty()) plan.bias = &masters.bias;
  if (!masters.darkPerS.empty()) plan.darkPerS = &masters.darkPerS;
  if (!masters.flat.empty()) plan.flat = &masters.flat;
  if (params.trim) plan.trimSec = trimSec;
  return plan;
}

void applyPixelCalibration(FrameCube& cube, const CalibrationPlan& plan, ProgressSink& progress,
                           CancelToken& cancel) {
  const std::size_t np = cube.framePixels();
  parallelFor(cube.frameCount(), 4, [&](std::size_t n0, std::size_t n1) {
    for (std::size_t n = n0; n < n1; ++n) {
      cancel.throwIfCancelled();
      float* f = cube.frame(n);
      const float os = plan.overscan[n];
      const float darkS = plan.darkSeconds[n];
      for (std::size_t i = 0; i < np; ++i) {
        float v = f[i] - os;
        if (plan.bias) v -= plan.bias->pixels[i];
        if (plan.darkPerS) v -= plan.darkPerS->pixels[i] * darkS;
        if (plan.flat) v /= plan.flat->pixels[i];
        f[i] = v;
      }
    }
    progress.report(static_cast<double>(n1) / cube.frameCount(), "calibrate");
  });
}

bool trims(const FrameCube& cube, const CalibrationPlan& plan) {
  const std::optional<Section>& t = plan.trimSec;
  return t && !(t->x0 == 0 && t->y0 == 0 && t->width == cube.width() && t->height == cube.height());
}

CalibrationReport finishCalibration(FrameCube& cube, const MasterCalibration& masters,
                                    CalibrationPlan& plan) {
  CalibrationReport rep = std::move(plan.report);
  const int w = cube.width(), h = cube.height();
  const std::size_t np = cube.framePixels();
  if (!masters.bad.empty()) {
    // The bad pixels listed once, then set in every frame on every core; a new mask is the kernel's zero
    // pages but where written (sparseZeros): a few pixels a frame in 393 MB for 1500 x 512^2, which were
    // zeroed whole and then scanned pixel by pixel in every frame on one thread.
    std::vector<std::size_t> bad;
    for (std::size_t i = 0; i < np; ++i)
      if (masters.bad[i] != 0) bad.push_back(i);
    if (!bad.empty()) {
      auto& mask = cube.mask();
      if (mask.empty()) mask = sparseZeros(cube.pixels().size());
      parallelFor(cube.frameCount(), 8, [&](std::size_t n0, std::size_t n1) {
        for (std::size_t n = n0; n < n1; ++n)
          for (const std::size_t i : bad)
            mask[n * np + i] = 1;
      });
    }
  }
  const std::optional<Section>& trimSec = plan.trimSec;
  if (trims(cube, plan)) trimInPlace(cube, *trimSec);
  rep.trimmedWidth = cube.width();
  rep.trimmedHeight = cube.height();
  if (!masters.bad.empty()) {
    const Section r = trimSec ? *trimSec : Section{0, 0, w, h};
    for (int y = r.y0; y < r.y0 + r.height; ++y)
      for (int x = r.x0; x < r.x0 + r.width; ++x)
        rep.badPixels += masters.bad[static_cast<std::size_t>(y) * w + x];
  }
  return rep;
}

CalibrationReport applyCalibration(FrameCube& cube, const MasterCalibration& masters,
                                   const CalibParams& params, ProgressSink& progress, CancelToken& cancel) {
  CalibrationPlan plan = planCalibration(cube, masters, params);
  applyPixelCalibration(cube, plan, progress, cancel);
  return finishCalibration(cube, masters, plan);
}

}  // namespace st::calib
