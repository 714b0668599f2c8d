#pragma once
// Loading frames from FITS: a 3-D cube, a list of 2-D files, or a folder (sorted by time); tile-compressed
// .fz and gzip .fits.gz; any image HDU. Bad input throws st::InputError / st::FitsError naming the file,
// HDU and keyword or value; nothing is half-loaded.
#include <optional>
#include <string>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/io/sections.hpp"

namespace st::io {

/// A crop to a common region (0-based first column/row, width, height); see st/io/sections.hpp.
using CropRegion = PixelRegion;

struct LoadOptions {
  /// HDU to read: a 1-based number or an EXTNAME. Default: the first image HDU with data.
  std::optional<std::string> hdu;
  /// For frames whose headers carry no time: start (MJD, UTC, mid-time of the first frame) and frame rate.
  std::optional<double> startMjd;
  std::optional<double> frameRateHz;
  /// Exposure length when headers have none (seconds).
  std::optional<double> exposureS;
  /// Crop every frame to this region (needed when frames differ in size).
  std::optional<CropRegion> crop;
  /// Plate scale to use when there is no WCS (arcsec/px); a WCS wins unless `forcePlateScale`.
  std::optional<double> plateScaleArcsecPerPx;
  bool forcePlateScale = false;
  /// The frames are science exposures: a file whose IMAGETYP or OBSTYPE says bias/zero, dark or flat, or
  /// whose EXPTIME is 0, gets a warning naming it (FrameCube::warnings, InputSummary::warnings). False when
  /// loading calibration frames.
  bool scienceFrames = true;
};

/// Loads every frame of `inputs` (files or folders) into one cube, frames sorted by mid-time (a warning in
/// cube.warnings when they were out of order). Reports progress per frame; throws st::Cancelled.
///
/// Pixels are read as float through CFITSIO (BZERO/BSCALE applied, any BITPIX); BLANK and NaN pixels are
/// set to 0 and flagged in cube.mask(). Times (mid-exposure, MJD UTC): from a "FRAMES" binary table or
/// MJD_<n> keywords for 3-D cubes, else per header (st/io/fits_time.hpp; a cube's DATE-OBS plus
/// FRAMERAT/CADENCE); when no frame has a time, options.startMjd + n / options.frameRateHz.
/// Files are read in parallel, one CFITSIO handle per thread. All checks (sizes, NAXIS, times, duplicates,
/// truncation) are done on the headers before any pixel is read. Throws st::InputError / st::FitsError
/// naming the file, HDU and keyword or value.
FrameCube loadFrames(const std::vector<std::string>& inputs, const LoadOptions& options,
                     ProgressSink& progress, CancelToken& cancel);

/// Convenience overload with default options and no progress.
FrameCube loadFrames(const std::vector<std::string>& inputs);

/// The celestial WCS of a frame or cube header, on its two image axes (a cube's NAXIS3 left out), as
/// loadFrames attaches it; null without one (the reasons in `warnings`).
std::shared_ptr<const Wcs> cubeWcs(const FitsHeader& header, std::vector<std::string>* warnings);

/// A short description of the inputs without reading all pixels (for `synthtrack-cli info`).
struct InputSummary {
  std::size_t frames = 0;
  int width = 0;
  int height = 0;
  /// CFITSIO's equivalent BITPIX (fits_get_img_equivtype): 8, 16, 32, 64, -32, -64, or 10 / 20 / 40 / 80 for
  /// signed bytes and unsigned 16/32/64-bit integers stored with the standard BZERO offsets.
  int bitpix = 0;
  double firstMjd = 0.0;
  double lastMjd = 0.0;
  double medianCadenceS = 0.0;
  double exposureS = 0.0;
  bool hasWcs = false;
  std::optional<double> plateScaleArcsecPerPx;
  std::vector<std::string> files;
  std::vector<std::string> warnings;
  // Added for `info`:
  int hdu = 0;                 ///< 1-based HDU of the image in the first file
  std::string timeSource;      ///< keywords the times came from, e.g. "DATE-OBS+UTCSTART (start) + EXPTIME/2"
  std::string wcsDescription;  ///< e.g. "RA---TAN-SIP / DEC--TAN-SIP, centre 303.2064 +46.0174"
  std::vector<double> mjdMid;  ///< every frame's mid-time, sorted
  FitsHeader header;           ///< the first frame's, describing the loaded 2-D frame (crop applied)
};

/// Describes `inputs` from their headers only (no pixels): the same checks and time rules as loadFrames,
/// so an input that summarizes without error loads. Throws like loadFrames.
InputSummary summarizeInputs(const std::vector<std::string>& inputs, const LoadOptions& options = {});

}  // namespace st::io
