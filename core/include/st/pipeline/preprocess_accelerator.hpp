#pragma once
// A device that can run the heavy pre-processing stages (issue 16): the per-pixel background (the clipped
// per-pixel statistics and the subtraction of stats::subtractPixelBackground) and the matched filter
// (stack::filterCube, weighted or not). The CPU functions stay the reference and the fallback: an
// implementation must give their results within float tolerance, and throw st::GpuError, leaving the cube as
// it was, when its device fails. core knows only this interface; the CUDA one is in gpu/
// (st::gpu::makeCudaPreprocessAccelerator).
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "st/calib/calibration.hpp"
#include "st/calib/cosmic_rays.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/detect/hot_pixels.hpp"
#include "st/detect/moving_mask.hpp"
#include "st/detect/registration.hpp"
#include "st/detect/sky_rate.hpp"
#include "st/detect/sky_stack.hpp"
#include "st/detect/star_subtraction.hpp"
#include "st/detect/static_sources.hpp"
#include "st/stack/matched_filter.hpp"
#include "st/stats/background.hpp"
#include "st/stats/noise_model.hpp"

namespace st::pipeline {

/// What pipeline::preprocess's stages from the per-pixel background to the residual means take (issue 16:
/// a device may run them all on one upload of the cube).
struct ZeroBiasInputs {
  stats::BackgroundParams background;
  const detect::MovingMask* exclude = nullptr;         ///< left out of the per-pixel background
  const detect::MovingMask* subtractRegion = nullptr;  ///< stars subtracted (drifting field) when not empty
  detect::StarSubtractionParams starSubtraction;
  const std::vector<std::uint64_t>* cosmicRayPixels = nullptr;  ///< zeroed (calib::zeroPixels)
  /// Zeroed in every frame (detect::zeroMasked); the star subtraction's excess positions are added to it.
  detect::MovingMask* starMask = nullptr;
  const detect::MovingMask* moverMask = nullptr;  ///< kept by zeroUnmeasured and zeroSingleFrameSources
  double singleFrameSnr = 5.0;
  int singleFrameRadiusPx = 1;
  bool removeResidualMean = true;
  int residualMeshPx = 64;
  double residualClipSigma = 5.0;
  /// The noise model the pipeline estimates next (estimateNoiseModel from the per-pixel sigma and the
  /// unmeasured pixels), when it does: a device may make its variance map on the host beside its own stages.
  const stats::NoiseModelParams* noiseModel = nullptr;
};

/// Their results; stageSeconds: "per-pixel background", "star subtraction" (when attempted), "zeroing",
/// "residual means", as pipeline::Prepared::stageSeconds.
struct ZeroBiasResult {
  stats::Background background;
  bool starsAttempted = false;  ///< subtractRegion was not empty
  detect::StarSubtraction starSubtraction;
  std::size_t staticPixelsZeroed = 0, unmeasuredPixelsZeroed = 0;
  detect::SingleFrameSources singleFrame;
  double residualMeanRms = 0.0;
  std::vector<std::pair<std::string, double>> stageSeconds;
};

class PreprocessAccelerator {
 public:
  virtual ~PreprocessAccelerator() = default;
  /// e.g. "cuda: NVIDIA H100 80GB HBM3", for notes and logs.
  [[nodiscard]] virtual std::string name() const = 0;
  /// How the last stage ran on the device (times of upload, kernels, download), for the notes; may be empty.
  [[nodiscard]] virtual std::string lastNote() const { return {}; }
  /// Waits for the downloads into the pipeline's cubes that a stage left running behind the stages after
  /// it (zeroBias's zero-biased cube, downloaded beside the noise model and the matched filter); the host
  /// cube may not be read or written before. Throws st::Error when one failed part way (the frames are half
  /// written). The pipeline calls it before the CPU does a stage the device failed, and before it returns;
  /// the device's own stages wait where they need the host copy. The default has none to wait for.
  virtual void finishHostCopies() {}
  /// The pipeline's word that it gates its reads of the host frames after removeFrameBackgrounds (or
  /// calibrateAndRemoveFrameBackgrounds) with waitForHostFrames and finishHostCopies: a device may then leave
  /// that stage's download of the frames running behind the stages after it (registration, the sky rate),
  /// which read the frames it keeps. Until the pipeline allows it (and once it says false again), that
  /// download is done when the stage returns. The default has none.
  virtual void allowFrameDownloadBehind(bool allow) { (void)allow; }
  /// Blocks until frames [first, end) of `cube` are on the host (the frame backgrounds' download behind, its
  /// pieces holding them moved to the front); throws st::Error when a download failed part way. May be
  /// called from several threads at once. The default has none to wait for.
  virtual void waitForHostFrames(const FrameCube& cube, std::size_t first, std::size_t end) {
    (void)cube, (void)first, (void)end;
  }
  /// Same contract as stats::removeFrameBackgrounds (SEP's background per frame): the same levels and rms
  /// (within the rounding of SEP's double sums), the frames within float rounding of the CPU's. The default
  /// is the CPU's.
  virtual stats::FrameBackgrounds removeFrameBackgrounds(FrameCube& cube,
                                                         const stats::FrameBackgroundParams& params,
                                                         ProgressSink& progress, CancelToken& cancel) {
    return stats::removeFrameBackgrounds(cube, params, progress, cancel);
  }
  /// calib::applyPixelCalibration(cube, plan) and then removeFrameBackgrounds(cube, params) in one (issue
  /// 16: a device applies the plan to the frames it uploads for the backgrounds, the same floats, instead of
  /// a pass of its own over the host cube). None when not supported, `cube` untouched (the caller does the
  /// two in turn); on st::GpuError `cube` is as it was. The default supports none.
  virtual std::optional<stats::FrameBackgrounds> calibrateAndRemoveFrameBackgrounds(
      FrameCube& cube, const calib::CalibrationPlan& plan, const stats::FrameBackgroundParams& params,
      ProgressSink& progress, CancelToken& cancel) {
    (void)cube, (void)plan, (void)params, (void)progress, (void)cancel;
    return std::nullopt;
  }
  /// Same contract as stats::globalBackground, mean and sigma within the rounding of its double sums (the
  /// same samples, count and passes). The default is the CPU's.
  virtual stats::ClipStats globalBackground(const FrameCube& cube,
                                            const stats::GlobalBackgroundParams& params) {
    return stats::globalBackground(cube, params);
  }
  /// The pipeline's word whether `cube`'s pixels are still those removeFrameBackgrounds(cube) left (the
  /// stages since changed only its mask and frame info; false: they may have changed). Until it says false,
  /// a device that kept those frames may use them for globalBackground, hotPixelExcess and the next
  /// prefetch(cube) instead of uploading the pixels; without a true it must not. The default does nothing.
  virtual void framesUnchangedSinceFrameBackgrounds(const FrameCube& cube, bool unchanged) {
    (void)cube, (void)unchanged;
  }
  /// Registration's sampled links (detect::RegistrationLinkBatch) from the frames the device kept from
  /// removeFrameBackgrounds (once framesUnchangedSinceFrameBackgrounds said true) and the host cube's mask;
  /// none when it cannot (no such frames, a transform size it does not take). Throws st::GpuError.
  virtual std::optional<std::vector<detect::RegistrationLinkPeak>> registrationLinks(
      const FrameCube& cube, const detect::RegistrationLinkBatch& batch) {
    (void)cube, (void)batch;
    return std::nullopt;
  }
  /// The smallest block-mean excess of each pixel that detect::findHotPixels computes (see
  /// detect::hotPixelsFromExcess: the same sums in the same order, so the same pixels); none when the device
  /// cannot make it without an upload of its own. The default makes none (the CPU finds the pixels).
  virtual std::optional<std::vector<float>> hotPixelExcess(const FrameCube& cube, double background,
                                                           const detect::HotPixelParams& params) {
    (void)cube, (void)background, (void)params;
    return std::nullopt;
  }
  /// The pipeline masked these pixels (y * width + x) in every frame of `cube`
  /// (detect::maskPixelsInAllFrames, after hotPixelExcess; also with none, when the mask did not change), and
  /// changed its mask in no other way since removeFrameBackgrounds: a device that kept that stage's frames
  /// and mask may apply the same to its copy of the mask instead of uploading the mask again at
  /// prefetch(cube). The default does nothing.
  virtual void maskedInAllFrames(const FrameCube& cube, const std::vector<std::size_t>& pixels) {
    (void)cube, (void)pixels;
  }
  /// `cube` is the input of the next subtractPixelBackground or zeroBias and does not change until then (the
  /// stages in between only read it) but at the pixels later passed to patchPrefetch: a device may start
  /// uploading it now, behind those stages. The returned guard (may be null) must be destroyed before the
  /// cube: its destructor waits for the upload.
  virtual std::shared_ptr<void> prefetch(const FrameCube& cube) {
    (void)cube;
    return nullptr;
  }
  /// The prefetched cube's pixels at these flat indices (n * width * height + y * width + x: the cosmic-ray
  /// fills) changed since prefetch(cube), nothing else: a device updates its copy, or drops it when it
  /// cannot (the stages after then upload the cube themselves). Never throws.
  virtual void patchPrefetch(const FrameCube& cube, const std::vector<std::uint64_t>& pixels) {
    (void)cube, (void)pixels;
  }
  /// detect::shiftedSums(cube, blocks, background) (the sky rate's block pairs and block stacks) in `form`:
  /// the same sums in the same order, or what `form` asks for made from them (detect::ShiftedSums); none
  /// when the device cannot make them without an upload of its own (`cube` is not the prefetched one, or
  /// its upload is not done yet). The default makes none.
  virtual std::optional<std::vector<detect::ShiftedSums>> shiftedSums(
      const FrameCube& cube, const std::vector<detect::ShiftedBlock>& blocks, double background,
      detect::ShiftedSumsForm form) {
    (void)cube, (void)blocks, (void)background, (void)form;
    return std::nullopt;
  }
  /// The sky rate's chain's phase correlations of one iteration (detect::PhaseCorrelationBatch): each pair's
  /// offset and response within the transforms' float rounding of the CPU's; none when the device does not
  /// make them (the CPU does). The default makes none.
  virtual std::optional<std::vector<detect::PhasePeak>> phaseCorrelations(
      const detect::PhaseCorrelationBatch& batch) {
    (void)batch;
    return std::nullopt;
  }
  /// detect::stackAtSkyRate(cube, rate, subtract, first, last) (last resolved, never 0): the same sums in
  /// the same order (equal stacks); none when the device cannot make it without a whole upload of its own
  /// (e.g. `cube` is not the one prefetch() took). The cube only needs to be unchanged since prefetch().
  /// The default makes none (the CPU stacks).
  virtual std::optional<detect::SkyStack> skyStack(const FrameCube& cube, Velocity rate, double subtract,
                                                   std::size_t first, std::size_t last) {
    (void)cube, (void)rate, (void)subtract, (void)first, (void)last;
    return std::nullopt;
  }
  /// calib::cosmicRayPreTestWords(cube, thr) (the seeds' pre-test of removeCosmicRays): the same words; none
  /// when the device cannot make it without an upload of its own (as skyStack). The default makes none.
  virtual std::optional<calib::CosmicRayPreTestWords> cosmicRayPreTest(const FrameCube& cube, float thr) {
    (void)cube, (void)thr;
    return std::nullopt;
  }
  /// The static sources' matched-filtered SNR of a stack at the sky rate (detect::FilteredSnrInputs): the
  /// same values, bit for bit; none when the device does not make it. The default makes none.
  virtual std::optional<std::vector<float>> filteredSnr(const detect::FilteredSnrInputs& in) {
    (void)in;
    return std::nullopt;
  }
  /// Same contract as stats::subtractPixelBackground.
  virtual stats::Background subtractPixelBackground(FrameCube& cube, const stats::BackgroundParams& params,
                                                    const detect::MovingMask* exclude, ProgressSink& progress,
                                                    CancelToken& cancel) = 0;
  /// Same contract as stats::removeResidualMeans (cell means within the rounding of its double sums). A
  /// device may keep the frames it leaves in `cube` and filter them without an upload when filterCubeFrom's
  /// source is this cube, unchanged in between (same buffer and sampled pixels). The default is the CPU's.
  virtual double removeResidualMeans(FrameCube& cube, int meshPx, double clipSigma, ProgressSink& progress,
                                     CancelToken& cancel) {
    return stats::removeResidualMeans(cube, meshPx, clipSigma, progress, cancel);
  }
  /// Same contract as stats::estimateNoiseModel: the same variance map, frame scales from the same order
  /// statistic. A device may read the frames removeResidualMeans or zeroBias left on it when `zeroBiased`
  /// is that cube unchanged. The default is the CPU's.
  virtual stats::NoiseModel estimateNoiseModel(const FrameCube& zeroBiased, const Image& pixelSigma,
                                               const std::vector<std::uint8_t>& unmeasured,
                                               const stats::NoiseModelParams& params, CancelToken& cancel) {
    return stats::estimateNoiseModel(zeroBiased, pixelSigma, unmeasured, params, cancel);
  }
  /// Same contract as stack::filterCube. `revision` (search::FilteredCube::revision, 0 = none): the
  /// filtered frames will carry it, so a device may keep them for the search under it.
  virtual stack::MatchedFilterResult filterCube(FrameCube& cube, const stack::FilterKernel& kernel,
                                                ProgressSink& progress, CancelToken& cancel,
                                                const stats::NoiseModel* noise, std::uint64_t revision) = 0;
  /// The matched filter of `source`'s pixels, unmasked (masked samples are 0 in a zero-biased cube), into
  /// `filtered`: its pixels become the filtered frames, its other fields are the caller's; `source` is
  /// unchanged. Same result as copying the pixels into `filtered` and calling filterCube on it (which is
  /// what this default does); a device reads `source` directly and writes `filtered` once, without the host
  /// copy of the cube (~1.4 s for 1500 x 512^2). On st::GpuError `filtered`'s pixels are unspecified.
  virtual stack::MatchedFilterResult filterCubeFrom(const FrameCube& source, FrameCube& filtered,
                                                    const stack::FilterKernel& kernel, ProgressSink& progress,
                                                    CancelToken& cancel, const stats::NoiseModel* noise,
                                                    std::uint64_t revision) {
    filtered.pixels() = source.pixels();
    filtered.mask().clear();
    return filterCube(filtered, kernel, progress, cancel, noise, revision);
  }
  /// The stages of zeroBiasStages (per-pixel background, star subtraction, the zeroing stages, residual
  /// means) with the cube kept on the device from one upload to one download; same results within the
  /// per-stage tolerances. False: not supported (the caller runs zeroBiasStages). On st::GpuError the host
  /// cube is as it was (the caller restores *in.starMask and runs zeroBiasStages). On return the host cube's
  /// download may still run: finishHostCopies() waits for it.
  virtual bool zeroBias(FrameCube& cube, const ZeroBiasInputs& in, ZeroBiasResult& out,
                        ProgressSink& progress, CancelToken& cancel) {
    (void)cube, (void)in, (void)out, (void)progress, (void)cancel;
    return false;
  }
};

/// The stages from the per-pixel background to the residual means one after the other (pipeline::preprocess
/// before issue 16's resident cube): per-pixel background and residual means through the *On functions
/// below, star subtraction and zeroing on the CPU. `progress` is the pipeline's (0.4 to 0.83).
ZeroBiasResult zeroBiasStages(PreprocessAccelerator* accel, FrameCube& cube, const ZeroBiasInputs& in,
                              ProgressSink& progress, CancelToken& cancel, std::vector<std::string>& notes);

/// accel->zeroBias when it is supported (adding its lastNote()); else, or on st::GpuError (a warning in
/// `notes`, *in.starMask restored), zeroBiasStages.
ZeroBiasResult zeroBiasOn(PreprocessAccelerator* accel, FrameCube& cube, const ZeroBiasInputs& in,
                          ProgressSink& progress, CancelToken& cancel, std::vector<std::string>& notes);

/// stats::removeFrameBackgrounds on `accel` when given, else (or on st::GpuError, with a warning in `notes`,
/// the cube as it was) on the CPU; a device run adds its lastNote().
stats::FrameBackgrounds removeFrameBackgroundsOn(PreprocessAccelerator* accel, FrameCube& cube,
                                                 const stats::FrameBackgroundParams& params,
                                                 ProgressSink& progress, CancelToken& cancel,
                                                 std::vector<std::string>& notes);

/// calib::applyPixelCalibration and then stats::removeFrameBackgrounds: on `accel` in one when it supports
/// that (adding its lastNote()); else (or on st::GpuError, with a warning in `notes`, the cube as it was)
/// the pixels on the CPU, then removeFrameBackgroundsOn.
stats::FrameBackgrounds calibrateAndRemoveFrameBackgroundsOn(PreprocessAccelerator* accel, FrameCube& cube,
                                                             const calib::CalibrationPlan& plan,
                                                             const stats::FrameBackgroundParams& params,
                                                             ProgressSink& progress, CancelToken& cancel,
                                                             std::vector<std::string>& notes);

/// stats::globalBackground on `accel` when given, else (or on st::GpuError, with a warning in `notes`) on
/// the CPU.
stats::ClipStats globalBackgroundOn(PreprocessAccelerator* accel, const FrameCube& cube,
                                    const stats::GlobalBackgroundParams& params,
                                    std::vector<std::string>& notes);

/// detect::findHotPixels against the global background `global`; on `accel` when given (its block-mean
/// excess, then detect::hotPixelsFromExcess's same selection), else (or on st::GpuError, with a warning in
/// `notes`) on the CPU.
std::vector<std::size_t> findHotPixelsOn(PreprocessAccelerator* accel, const FrameCube& cube,
                                         const stats::ClipStats& global, const detect::HotPixelParams& params,
                                         CancelToken& cancel, std::vector<std::string>& notes);

/// stats::estimateNoiseModel on `accel` when given, else (or on st::GpuError, with a warning in `notes`) on
/// the CPU; a device run adds its lastNote().
stats::NoiseModel estimateNoiseModelOn(PreprocessAccelerator* accel, const FrameCube& zeroBiased,
                                       const Image& pixelSigma, const std::vector<std::uint8_t>& unmeasured,
                                       const stats::NoiseModelParams& params, CancelToken& cancel,
                                       std::vector<std::string>& notes);

/// stats::removeResidualMeans on `accel` when given, else (or on st::GpuError, with a warning in `notes`) on
/// the CPU; a device run adds its lastNote().
double removeResidualMeansOn(PreprocessAccelerator* accel, FrameCube& cube, int meshPx, double clipSigma,
                             ProgressSink& progress, CancelToken& cancel, std::vector<std::string>& notes);

/// stats::subtractPixelBackground on `accel` when given, else (or when the device fails: st::GpuError) on
/// the CPU; a device failure adds a warning to `notes` naming the stage and the device's message, a device
/// run its lastNote().
stats::Background subtractPixelBackgroundOn(PreprocessAccelerator* accel, FrameCube& cube,
                                            const stats::BackgroundParams& params,
                                            const detect::MovingMask* exclude, ProgressSink& progress,
                                            CancelToken& cancel, std::vector<std::string>& notes);

/// stack::filterCube on `accel` when given, else (or on st::GpuError, with a warning in `notes`) on the CPU.
stack::MatchedFilterResult filterCubeOn(PreprocessAccelerator* accel, FrameCube& cube,
                                        const stack::FilterKernel& kernel, ProgressSink& progress,
                                        CancelToken& cancel, const stats::NoiseModel* noise,
                                        std::vector<std::string>& notes, std::uint64_t revision = 0);

/// PreprocessAccelerator::filterCubeFrom on `accel` when given, else (or on st::GpuError, with a warning in
/// `notes`) the CPU's stack::filterCube on a copy of `source`'s pixels in `filtered`.
stack::MatchedFilterResult filterCubeFromOn(PreprocessAccelerator* accel, const FrameCube& source,
                                            FrameCube& filtered, const stack::FilterKernel& kernel,
                                            ProgressSink& progress, CancelToken& cancel,
                                            const stats::NoiseModel* noise, std::vector<std::string>& notes,
                                            std::uint64_t revision = 0);

}  // namespace st::pipeline
