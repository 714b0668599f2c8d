#include "load_plan.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <set>

#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/common/units.hpp"

namespace st::io::detail {
namespace {

// Two frames closer than this are the same frame given twice (MJD doubles resolve ~1 microsecond).
constexpr double kDuplicateToleranceS = 1e-5;

std::string sizeText(int w, int h) {
  return std::to_string(w) + "x" + std::to_string(h);
}

void checkSizes(LoadPlan& plan, const LoadOptions& options) {
  const ScannedFile& first = plan.files.front();
  if (options.crop) {
    const PixelRegion& c = *options.crop;
    for (const auto& f : plan.files) {
      if (c.width <= 0 || c.height <= 0 || c.x0 < 0 || c.y0 < 0 || c.x0 + c.width > f.width ||
          c.y0 + c.height > f.height) {
        throw InputError(f.path + " HDU " + std::to_string(f.hdu) +
                         ": crop region x0=" + std::to_string(c.x0) + " y0=" + std::to_string(c.y0) + " " +
                         sizeText(c.width, c.height) + " does not fit inside the frame of " +
                         sizeText(f.width, f.height));
      }
    }
    plan.region = c;
    plan.cropped = true;
    return;
  }
  for (const auto& f : plan.files) {
    if (f.width != first.width || f.height != first.height) {
      throw InputError(f.path + " HDU " + std::to_string(f.hdu) + ": frame size " +
                       sizeText(f.width, f.height) + " differs from " + sizeText(first.width, first.height) +
                       " of " + first.path +
                       "; crop every frame to a common region (--crop [x1:x2,y1:y2] on the command line)");
    }
  }
  plan.region = PixelRegion{0, 0, first.width, first.height};
}

void assignTimes(LoadPlan& plan, const LoadOptions& options) {
  std::size_t known = 0;
  for (const auto& f : plan.frames)
    known += f.mjdMid.has_value() ? 1 : 0;
  if (known == 0) {
    if (!options.startMjd || !options.frameRateHz) {
      const ScannedFile& f = plan.files.front();
      throw InputError(
          f.path + " HDU " + std::to_string(f.hdu) +
          ": no timestamps: the header has none of DATE-OBS with a time, DATE-OBS + TIME-OBS/UTCSTART/UT, "
          "MJD-OBS, DATE-AVG, MJD-AVG (nor a FRAMES table); give the first frame's mid-time and the "
          "frame rate (--start-mjd MJD --frame-rate HZ on the command line)");
    }
    if (!(*options.frameRateHz > 0.0) || !std::isfinite(*options.startMjd)) {
      throw InputError("frame rate must be > 0 Hz and the start MJD finite, got " +
                       std::to_string(*options.frameRateHz) + " Hz");
    }
    for (std::size_t n = 0; n < plan.frames.size(); ++n) {
      plan.frames[n].mjdMid =
          *options.startMjd + static_cast<double>(n) / *options.frameRateHz / kSecondsPerDay;
    }
    plan.timeSource = "--start-mjd + frame index / --frame-rate (input order)";
  } else if (known < plan.frames.size()) {
    for (const auto& f : plan.frames) {
      if (!f.mjdMid) {
        throw InputError(describeFrame(plan, f) + ": has no timestamp while " + std::to_string(known) +
                         " other frames do (DATE-OBS, MJD-OBS, ...); fix its header or leave it out");
      }
    }
  } else {
    plan.timeSource = plan.files.front().timeSource;
  }
  for (auto& f : plan.frames) {
    if (!f.exposureS && options.exposureS) f.exposureS = options.exposureS;
  }
}

void sortAndCheckTimes(LoadPlan& plan) {
  auto& fr = plan.frames;
  const bool sorted = std::is_sorted(fr.begin(), fr.end(),
                                     [](const auto& a, const auto& b) { return *a.mjdMid < *b.mjdMid; });
  if (!sorted) {
    std::size_t bad = 1;
    while (bad < fr.size() && *fr[bad].mjdMid >= *fr[bad - 1].mjdMid)
      ++bad;
    plan.warnings.push_back("frames were not in time order (first out of order: " +
                            describeFrame(plan, fr[bad]) + "); sorted by mid-time");
    std::stable_sort(fr.begin(), fr.end(),
                     [](const auto& a, const auto& b) { return *a.mjdMid < *b.mjdMid; });
  }
  for (std::size_t n = 1; n < fr.size(); ++n) {
    if ((*fr[n].mjdMid - *fr[n - 1].mjdMid) * kSecondsPerDay < kDuplicateToleranceS) {
      char mjd[40];
      std::snprintf(mjd, sizeof mjd, "%.8f", *fr[n].mjdMid);
      throw InputError("duplicate frame time MJD " + std::string(mjd) + ": " +
                       describeFrame(plan, fr[n - 1]) + " and " + describeFrame(plan, fr[n]) +
                       " (the same frame given twice, or wrong time keywords)");
    }
  }
}

}  // namespace

std::string describeFrame(const LoadPlan& plan, const PlaneRef& frame) {
  const ScannedFile& f = plan.files[frame.fileIndex];
  std::string s = f.path + " HDU " + std::to_string(f.hdu);
  if (f.planes > 1) s += " plane " + std::to_string(frame.plane + 1);
  return s;
}

LoadPlan planLoad(const std::vector<std::string>& inputs, const LoadOptions& options, ProgressSink& progress,
                  CancelToken& cancel) {
  const std::vector<std::string> paths = expandInputs(inputs);
  LoadPlan plan;
  plan.files.resize(paths.size());
  std::atomic<std::size_t> done{0};
  parallelFor(paths.size(), 1, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      cancel.throwIfCancelled();
      plan.files[i] = scanFile(paths[i], i, options);
      progress.report(static_cast<double>(++done) / static_cast<double>(paths.size()), "reading headers");
    }
  });
  checkSizes(plan, options);
  std::set<std::string> seen;
  for (auto& f : plan.files) {
    plan.frames.insert(plan.frames.end(), f.frames.begin(), f.frames.end());
    for (auto& w : f.warnings) {
      if (seen.insert(w).second) plan.warnings.push_back(w);
    }
  }
  assignTimes(plan, options);
  sortAndCheckTimes(plan);
  return plan;
}

}  // namespace st::io::detail
