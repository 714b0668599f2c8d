#pragma once
// Detector calibration (paper §4.2, "The pre-processing procedure"): master bias (per-pixel median), an
// optional master dark scaled by exposure, a normalised master flat, overscan (BIASSEC) subtraction, TRIMSEC
// trim and a bad/hot-pixel mask. Masters are built once from raw calibration frames (as loaded, untrimmed)
// and applied to the science cube in place.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "st/calib/section.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"

namespace st::calib {

struct CalibParams {
  bool subtractOverscan = true;  ///< subtract the median of BIASSEC from each frame when it is known
  bool trim = true;              ///< trim every frame to TRIMSEC (else DATASEC) when it is known
  /// Read BIASSEC, TRIMSEC and DATASEC from the headers. A header section that does not fit the frames is
  /// clipped to them, or ignored when nothing is left, with a warning (calibration reports); false ignores
  /// them all (the CLI's --ignore-sections), for headers that describe another readout.
  bool useHeaderSections = true;
  std::optional<Section> biasSec;  ///< overrides the header's BIASSEC (0-based)
  std::optional<Section> trimSec;  ///< overrides the header's TRIMSEC (0-based)
  double hotSigma = 8.0;           ///< hot pixel: master dark (or bias) above clip mean + hotSigma * sigma
  double flatLow = 0.2;            ///< bad pixel: normalised flat below this (or <= 0); real flats are
                                   ///< vignetted to ~0.3 in corners (Lowell 42-inch), which stays usable
  double flatHigh = 2.0;           ///< ... or above this
};

/// Masters at the raw (untrimmed) frame size. Empty images mean "not given".
struct MasterCalibration {
  int width = 0;  ///< raw frame size the masters were built for
  int height = 0;
  std::string binning;            ///< the calibration frames' binning (CCDSUM/XBINNING...), empty if unknown
  Image bias;                     ///< per-pixel median of the bias frames (overscan-subtracted), counts
  Image darkPerS;                 ///< median of (dark - bias) / EXPTIME, counts per second
  Image flat;                     ///< normalised flat (median 1); 1 where it was unusable (then masked)
  std::vector<std::uint8_t> bad;  ///< 1 = bad pixel (hot, or unusable flat), raw size; empty = none
  std::size_t hotPixels = 0;      ///< from the dark (or bias) outliers
  std::size_t flatNonPositive = 0;  ///< flat pixels <= 0 (or not finite) after bias subtraction
  std::size_t flatOutliers = 0;     ///< flat pixels outside [flatLow, flatHigh] after normalisation
  std::optional<Section> biasSec;   ///< the overscan used (from params or the calibration headers)
  std::optional<Section> trimSec;
  std::vector<std::string> warnings;  ///< header sections clipped or ignored, naming the file and keyword
};

/// Builds the masters. `bias` is required unless all three are empty; `dark` and `flat` are optional (empty
/// cubes). `science` is only used to check sizes and binning and to find BIASSEC/TRIMSEC/DATASEC (header
/// sections that do not fit are clipped or ignored, with a warning in `warnings`). Throws
/// st::InputError naming both sizes and the file when a calibration frame differs in size or binning from
/// the science frames, and when a flat has no positive pixel.
MasterCalibration buildMasters(const FrameCube& bias, const FrameCube& dark, const FrameCube& flat,
                               const FrameCube& science, const CalibParams& params, ProgressSink& progress,
                               CancelToken& cancel);

struct CalibrationReport {
  std::vector<float> overscanLevel;  ///< per frame, counts (empty without overscan)
  std::size_t badPixels = 0;         ///< pixels masked per frame (after trim)
  int trimmedWidth = 0;
  int trimmedHeight = 0;
  std::vector<std::string> warnings;  ///< header sections clipped or ignored, naming the file and keyword
};

/// Applies the masters to `cube` in place: overscan, bias, dark * EXPTIME, flat; bad pixels are set in the
/// cube's mask; then the trim (the pixel buffer is compacted in place, no second cube). Without masters
/// (`masters` empty) only overscan and trim are done, from params or the cube's header (a header section
/// that does not fit is clipped or ignored, with a warning in the report). Throws st::InputError on a size
/// mismatch (naming both sizes and the file), and when a section given in `params` does not fit.
CalibrationReport applyCalibration(FrameCube& cube, const MasterCalibration& masters,
                                   const CalibParams& params, ProgressSink& progress, CancelToken& cancel);

/// applyCalibration in three steps, so that a device may make the pixel arithmetic part of its upload
/// (issue 16): plan (inputs checked, the overscan levels measured), the pixels, then finish (bad pixels
/// masked, the trim). The bad pixels do not depend on the pixel values: where no trim follows, finish may
/// run before the pixels.
struct CalibrationPlan {
  /// Frame n's pixels become ((((f - overscan[n]) - bias) - darkPerS * darkSeconds[n]) / flat) in float,
  /// each master's step only where it is given (not null).
  std::vector<float> overscan, darkSeconds;  ///< per frame
  const Image* bias = nullptr;
  const Image* darkPerS = nullptr;
  const Image* flat = nullptr;
  std::optional<Section> trimSec;  ///< the trim finish applies (none, or the whole frame: no trim)
  CalibrationReport report;        ///< overscan levels and warnings so far
};
/// Throws as applyCalibration does. `masters` must outlive the plan.
CalibrationPlan planCalibration(const FrameCube& cube, const MasterCalibration& masters,
                                const CalibParams& params);
void applyPixelCalibration(FrameCube& cube, const CalibrationPlan& plan, ProgressSink& progress,
                           CancelToken& cancel);
CalibrationReport finishCalibration(FrameCube& cube, const MasterCalibration& masters, CalibrationPlan& plan);
/// True when finishCalibration will trim `cube` (then the pixels must come first).
bool trims(const FrameCube& cube, const CalibrationPlan& plan);

/// The region (0-based) that applyCalibration trims frames of `width` x `height` px with `header` to
/// (params.trimSec, else TRIMSEC, else DATASEC; clipped or ignored as it does, with its warnings); none when
/// it keeps the whole frame. Out-of-core pre-processing maps its strips onto the trimmed image with it.
std::optional<Section> trimRegion(const FitsHeader& header, int width, int height, const std::string& file,
                                  const CalibParams& params, std::vector<std::string>& warnings);

/// The masters of `region` (0-based, inside the masters' frame) of the frame they were built for: images
/// and bad-pixel mask cropped, BIASSEC/TRIMSEC moved into the region and clipped to it (none when nothing
/// is left). Out-of-core pre-processing builds the masters once for the whole frame and crops them to each
/// strip, so that every strip is calibrated with the same normalised flat. Throws st::InputError when the
/// region leaves the frame.
MasterCalibration cropMasters(const MasterCalibration& masters, const Section& region);

/// The binning of a header as text ("3 3"), from CCDSUM, or XBINNING/YBINNING, or BINNING; empty if absent.
std::string binningOf(const FitsHeader& header);

/// Per-pixel median over the frames of a cube (unmasked samples), the master-bias combiner.
Image medianCombine(const FrameCube& cube, CancelToken& cancel);

}  // namespace st::calib
