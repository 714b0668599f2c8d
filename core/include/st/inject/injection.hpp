#pragma once
// Injection of synthetic movers into real frames (ARCHITECTURE.md, "Validation beyond the simulator"), as
// survey pipelines validate themselves: movers of known position, velocity and expected SNR are added to
// copies of the RAW frames, the copies go through the whole pipeline, and `recovery` (st/inject/recovery.hpp)
// scores what the search found against the truth.
//
// Each mover: the field's Moffat PSF (st/inject/field.hpp) trailed over each exposure (st/inject/trail.hpp),
// position linear in time from (x, y) at t_ref, placed away from stars and inside the frame over the whole
// span, with a flux chosen for a requested expected SNR:
//   SNR^2 = sum_n sum_q (flux P_n(q))^2 / sigma_n^2,
// sigma_n the local frame-to-frame noise of frame n around the track (calibrated counts). Positions are in
// the calibrated (trimmed) frame, the frame the search reports in. In RAW counts the signal is multiplied
// by the normalised master flat at its raw pixel (so that the calibrated frames see the intended flux), and
// Poisson noise at the gain is drawn for it: Poisson(counts * gain) / gain.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "st/calib/calibration.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"
#include "st/inject/field.hpp"
#include "st/inject/trail.hpp"

namespace st::inject {

struct InjectParams {
  int count = 40;             ///< movers to inject
  double snrMin = 4.0;        ///< expected SNR, uniform in [snrMin, snrMax]
  double snrMax = 20.0;
  double rateMinPxS = 0.0;    ///< speed in the frames, px/s, uniform in [rateMin, rateMax]; direction uniform
  double rateMaxPxS = 0.01;
  std::uint64_t seed = 1;
  double minStarDistancePx = 0.0;  ///< track centre to the nearest star/bad pixel; 0 = max(5, 3 FWHM)
  double edgeMarginPx = 0.0;       ///< track centre to the frame edge; 0 = max(10, 3 FWHM)
  double minSeparationPx = 0.0;    ///< between two movers at the same time; 0 = max(10, 5 FWHM)
  std::optional<double> zeroPointMag;  ///< magnitude of 1 calibrated count per second; none = no magnitudes
  double lostFluxFraction = 1e-3;  ///< stamp radius (stampRadiusPx)
  int triesPerObject = 5000;       ///< random positions tried per mover before giving up
};

/// One injected mover. Positions are 0-based pixels of the calibrated frame at t_ref.
struct InjectedObject {
  int id = 0;
  double xPx = 0.0;
  double yPx = 0.0;
  double vxPxS = 0.0;
  double vyPxS = 0.0;
  double flux = 0.0;          ///< calibrated counts per frame (the whole PSF, over the exposure)
  double expectedSnr = 0.0;   ///< the optimal matched-filter SNR of the whole track
  std::optional<double> magnitude;
  std::vector<double> frameNoise;  ///< sigma_n around the track, calibrated counts
  double minMaskDistancePx = 0.0;  ///< closest approach of the track centre to a star/bad pixel
  std::vector<Stamp> stamps;       ///< unit-flux image in each frame (calibrated geometry)
};

/// The movers and everything needed to render them.
struct InjectionPlan {
  InjectParams params;        ///< with the defaults resolved (distances in px)
  double tRefMjd = 0.0;
  std::vector<double> tOffsetS;   ///< t_n - t_ref per frame
  std::vector<double> exposureS;
  int width = 0;                  ///< calibrated frame size
  int height = 0;
  psf::Moffat psf;
  bool psfMeasured = false;
  double stampRadiusPx = 0.0;
  std::vector<InjectedObject> objects;
};

/// Chooses the movers (seeded: the same cube, field and params give the same plan): speed and direction,
/// then (x, y) at t_ref uniformly until the track (every frame's start, middle and end, and every pixel of
/// motion between) keeps edgeMarginPx from the edges, minStarDistancePx from the field's mask and
/// minSeparationPx from the movers already placed at the same times; then the local noise around the track
/// (localFrameNoise over its stamps' bounding box grown by 10 px), the stamps, and the flux for an expected
/// SNR drawn in [snrMin, snrMax]. Throws st::InputError naming the values when params are invalid or when
/// a mover cannot be placed (too many movers, too large distances for the field). Throws st::Cancelled.
InjectionPlan planInjection(const FrameCube& calibrated, const Field& field, const InjectParams& params,
                            CancelToken& cancel);

/// Where the calibrated frame lies in the raw one, and what turns calibrated counts into raw ones.
struct RawGeometry {
  int width = 0;    ///< raw frame size
  int height = 0;
  int offsetX = 0;  ///< raw x of calibrated x = 0 (TRIMSEC start)
  int offsetY = 0;
  Image flat;       ///< normalised master flat at raw size; empty = 1
  double gainEPerAdu = 0.0;  ///< for the Poisson noise; <= 0: no noise (expected counts only)
  /// EM multiplication of an EMCCD (the header's EMGAIN; 1 = none): the signal's photo-electrons are
  /// gainEPerAdu / emGain per count, and go through the EM register (sim::emRegister), whose excess noise
  /// doubles their variance, as the simulator renders them.
  double emGain = 1.0;
  /// The raw frames hold integers (BITPIX > 0): the signal is rounded to whole counts stochastically (up
  /// with probability equal to the fraction), so that adding it to an integer frame loses no flux on
  /// average; plain rounding would drop every wing pixel below half a count.
  bool integerCounts = false;
};

/// The geometry of `raw` (as loaded) under the calibration `preprocess` applies with `masters` and
/// `params`: the trim offset (the masters' TRIMSEC when there is a master bias, else params' or the
/// header's), the masters' flat, integerCounts from the header's BITPIX and emGain from its EMGAIN. The gain
/// is left 0 for the caller.
RawGeometry rawGeometry(const FrameCube& raw, const calib::MasterCalibration& masters,
                        const calib::CalibParams& params);

/// The injected signal of frame `frame` in raw counts at raw size: every mover's flux x stamp x flat,
/// then Poisson(counts x gain) / gain per pixel (with emGain > 1: emRegister(Poisson(counts x gain /
/// emGain), emGain) / gain), then stochastic rounding when integerCounts (one random
/// stream per frame, seeded by the plan's seed and the frame: deterministic).
Image rawSignal(const InjectionPlan& plan, std::size_t frame, const RawGeometry& geometry);

/// Adds rawSignal to every frame of `raw` (in memory; tests and callers that write cubes themselves).
void addToCube(FrameCube& raw, const InjectionPlan& plan, const RawGeometry& geometry);

/// The magnitude of `flux` calibrated counts per frame of `exposureS` seconds under a zero point (the
/// magnitude of 1 count/s): zp - 2.5 log10(flux / exposureS).
double magnitudeOf(double flux, double exposureS, double zeroPointMag);

/// What injectIntoFiles did.
struct InjectionRun {
  InjectionPlan plan;
  Field field;
  RawGeometry geometry;
  std::vector<std::string> inputs;   ///< every input file, in frame order
  std::vector<std::string> written;  ///< the copies, same order
  std::size_t clippedPixels = 0;     ///< sums beyond the raw type's range (saturated)
};
/// Everything `synthtrack-cli inject` does, after loading: calibrates `raw` (moved in) like `preprocess`,
/// measures the field, plans the movers and writes a copy of every input file into `outDir` with the
/// signal added (io::copyWithAddedPixels: same HDU numbers and headers, .fz/.gz written uncompressed
/// under the name without that suffix, plus one HISTORY card and STINJECT = number of movers). Returns
/// the plan; `written` gets the paths written, `field` the field measured. Throws st::InputError for a
/// name clash between inputs, st::FitsError on write errors, st::Cancelled.
InjectionRun injectIntoFiles(FrameCube raw, const calib::MasterCalibration& masters,
                             const calib::CalibParams& calibParams, const FieldParams& fieldParams,
                             const InjectParams& params, double gainEPerAdu, const std::string& outDir,
                             ProgressSink& progress, CancelToken& cancel);

/// The output name of an input file: its file name without a trailing .fz or .gz, with ".fits" appended
/// when what remains does not end in .fits, .fit or .fts.
std::string injectedFileName(const std::string& input);

}  // namespace st::inject
