#pragma once
// Internal to core/io: everything loadFrames decides from the headers before reading a pixel: the files,
// the common frame region, every frame's time, the time order. Shared by loadFrames and summarizeInputs.
#include <string>
#include <vector>

#include "input_scan.hpp"
#include "st/common/progress.hpp"

namespace st::io::detail {

struct LoadPlan {
  std::vector<ScannedFile> files;
  std::vector<PlaneRef> frames;  ///< sorted by mid-time; every one has mjdMid
  PixelRegion region;            ///< region of each frame to read (the whole frame unless cropped)
  bool cropped = false;
  std::string timeSource;
  std::vector<std::string> warnings;
};

/// Scans the headers of `inputs` (in parallel, one CFITSIO handle per thread) and checks them. Progress goes
/// to `progress` as fractions of [0, 1]. Throws st::InputError / st::FitsError / st::Cancelled.
LoadPlan planLoad(const std::vector<std::string>& inputs, const LoadOptions& options, ProgressSink& progress,
                  CancelToken& cancel);

/// "file HDU n" or "file HDU n plane p" (1-based plane) for messages.
std::string describeFrame(const LoadPlan& plan, const PlaneRef& frame);

}  // namespace st::io::detail
