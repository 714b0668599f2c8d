#pragma once
// The CUDA pre-processing accelerator (gpu/include/st/gpu/preprocess.hpp), one class whose stages live in
// one file each (issue 16):
//   cuda_preprocess.cpp             the device, globalBackground, prefetch, the staged copies, the factory
//   cuda_preprocess_frame_backgrounds.cpp  the frame backgrounds (SEP per frame: frame_backgrounds.*)
//   cuda_preprocess_registration.cpp  registration's sampled links from the frame backgrounds' frames
//   cuda_preprocess_sky_stack.cpp  the stacks from the prefetched cube: the sky rate's block sums, the
//                                  cosmic-ray fills patched in, the stacks at the sky rate (static sources,
//                                  PSF) and their filtered SNR maps
//   cuda_preprocess_background.cpp the per-pixel background (subtractPixelBackground)
//   cuda_preprocess_zero_bias.cpp  zeroBias: the per-pixel background to the residual means on one upload
//   cuda_preprocess_residuals.cpp  removeResidualMeans and estimateNoiseModel
//   cuda_preprocess_filter.cpp     the matched filter (filterCube, filterCubeFrom)
//   host_copies.*                  the downloads that run behind the stages after them
// Host side: the CPU's tables (frames used, windows, weights) are made exactly as core makes them, the
// kernels (preprocess_kernels.cu, zero_bias_kernels.cu, ...) do the per-pixel and per-frame work, and the
// host cube is written only after every kernel has succeeded, so a st::GpuError leaves it as it was (the
// caller falls back to the CPU).
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <cstdio>
#include <exception>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "cuda_check.hpp"
#include "device_info.hpp"
#include "host_copies.hpp"
#include "resident_cube.hpp"
#include "st/common/trace.hpp"
#include "st/gpu/preprocess.hpp"
#include "uploader.hpp"

namespace st::gpu {

namespace preprocess_detail {

template <class T>
std::vector<T> toHost(const DeviceBuffer<T>& d, std::size_t count) {
  std::vector<T> out(count);
  if (count) ST_CUDA_CHECK(cudaMemcpy(out.data(), d.get(), count * sizeof(T), cudaMemcpyDeviceToHost));
  return out;
}

class Stopwatch {
 public:
  double lap() {
    const auto now = std::chrono::steady_clock::now();
    const double s = std::chrono::duration<double>(now - m_last).count();
    m_last = now;
    return s;
  }

 private:
  std::chrono::steady_clock::time_point m_last = std::chrono::steady_clock::now();
};

inline std::string ms(double s) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f ms", s * 1e3);
  return text;
}

/// Benchmark knob: ST_GPU_STAGEWISE=1 runs the pre-processing as before the resident zero-biased cube (the
/// cube uploaded and downloaded by the per-pixel background and again by the residual means, star
/// subtraction, zeroing and the noise model on the CPU, no prefetch), for before/after figures from one
/// binary.
inline bool stagewise() {
  return envKnob("ST_GPU_STAGEWISE");
}

/// Benchmark knob: ST_GPU_SYNC_DOWNLOADS=1 downloads the zero-biased and the filtered cubes with the device
/// idle, as before 2026-12-02 (HostCopies), for before/after figures from one binary.
inline bool syncDownloads() {
  return envKnob("ST_GPU_SYNC_DOWNLOADS");
}

/// Benchmark knob: ST_GPU_BLOCK_PAIRS_ON_HOST=1 makes the sky rate's block pairs' means on the CPU (as before
/// 2026-12-02's tenth stop) instead of the device (shiftedSums' DoubleMeans, the host's division bit for bit:
/// GpuSkyStack.BlockSumsAndPatchedPixelsEqualTheCpu), for before/after figures from one binary.
inline bool blockPairsOnHost() {
  return envKnob("ST_GPU_BLOCK_PAIRS_ON_HOST");
}

/// Benchmark knob: ST_GPU_PHASE_CORRELATIONS_ON_HOST=1 leaves the sky rate's chain's phase correlations to
/// the CPU's FFTW (the chain's links as before 2026-12-02's tenth stop: a declined first group hands them all
/// to the CPU's loop), for before/after figures from one binary.
inline bool phaseCorrelationsOnHost() {
  return envKnob("ST_GPU_PHASE_CORRELATIONS_ON_HOST");
}

/// Device -> pageable host through the two pinned staging buffers (the host copy of one piece on every
/// core while the next piece's DMA runs).
/// `copyThreads` bounds the threads of the host copy (0: every core); `chunkBytes` (0: a staging buffer's)
/// the size of each DMA, so that other streams' copies wait at most one such chunk on the copy engine.
/// `waiters`: while it is positive (someone waits for this download), each piece's host copy runs on every
/// core whatever copyThreads; ST_GPU_COPY_CAP_WHILE_WAITED=1 keeps the cap.
void download(DeviceResources& r, void* host, const void* dev, std::size_t bytes, cudaStream_t s,
              unsigned copyThreads = 0, std::size_t chunkBytes = 0,
              const std::atomic<int>* waiters = nullptr);

/// One region of a gathered download (downloadPieces).
struct DownloadPiece {
  void* host;
  const void* dev;
  std::size_t bytes;
};

/// The pieces' device -> host copies as one download: packed into the staging buffers a buffer at a time
/// (one sync a buffer, not one a piece), the next buffer's DMAs queued while this one is copied out on
/// every core. For many small results (the sky rate's 32 block means, a stack's three images): each piece's
/// own download() waited behind the frames' download on the copy engine (0.2-1.1 ms a piece, H200
/// 2026-12-03). ST_GPU_GATHER_DOWNLOADS=0 downloads them one by one, as before.
void downloadPieces(DeviceResources& r, const std::vector<DownloadPiece>& pieces, cudaStream_t s);

/// download() into the pipeline's own cube, in place: a failure part way leaves it half written, so it is
/// not a GpuError (whose contract is a cube as it was, for the CPU to process again) but an Error that
/// stops the run, naming `what` and `device`.
void downloadInPlace(DeviceResources& r, void* host, const void* dev, std::size_t bytes, cudaStream_t s,
                     const std::string& what, const std::string& device);

}  // namespace preprocess_detail

class CudaPreprocess final : public CudaPreprocessAccelerator {
 public:
  /// Starts making the device's streams and pinning its two staging buffers on a thread of its own
  /// (cudaMallocHost of 64 MiB took 29-73 ms on H100 hosts: otherwise the first upload, the frame
  /// backgrounds', waits for it); resources() waits for that thread.
  explicit CudaPreprocess(DeviceInfo device);

  [[nodiscard]] std::string name() const override { return "cuda: " + m_device.name; }
  [[nodiscard]] std::string lastNote() const override { return m_note; }  // the last stage's
  void setKeepResident(bool keep) override { m_keepResident = keep; }
  void finishHostCopies() override {
    const trace::Scope waiting("waits for the host copies");
    std::exception_ptr e = m_copies.wait();
    m_framesPendingData = nullptr;
    if (e) std::rethrow_exception(e);
  }
  void allowFrameDownloadBehind(bool allow) override { m_frameDownloadBehind = allow; }
  void waitForHostFrames(const FrameCube& cube, std::size_t first, std::size_t end) override;

  stats::FrameBackgrounds removeFrameBackgrounds(FrameCube& cube, const stats::FrameBackgroundParams& params,
                                                 ProgressSink& progress, CancelToken& cancel) override;
  std::optional<stats::FrameBackgrounds> calibrateAndRemoveFrameBackgrounds(
      FrameCube& cube, const calib::CalibrationPlan& plan, const stats::FrameBackgroundParams& params,
      ProgressSink& progress, CancelToken& cancel) override;
  stats::ClipStats globalBackground(const FrameCube& cube,
                                    const stats::GlobalBackgroundParams& params) override;
  void framesUnchangedSinceFrameBackgrounds(const FrameCube& cube, bool unchanged) override;
  std::optional<std::vector<float>> hotPixelExcess(const FrameCube& cube, double background,
                                                   const detect::HotPixelParams& params) override;
  std::optional<std::vector<detect::RegistrationLinkPeak>> registrationLinks(
      const FrameCube& cube, const detect::RegistrationLinkBatch& batch) override;
  double removeResidualMeans(FrameCube& cube, int meshPx, double clipSigma, ProgressSink& progress,
                             CancelToken& cancel) override;
  void maskedInAllFrames(const FrameCube& cube, const std::vector<std::size_t>& pixels) override;
  std::shared_ptr<void> prefetch(const FrameCube& cube) override;
  void patchPrefetch(const FrameCube& cube, const std::vector<std::uint64_t>& pixels) override;
  std::optional<std::vector<detect::ShiftedSums>> shiftedSums(const FrameCube& cube,
                                                              const std::vector<detect::ShiftedBlock>& blocks,
                                                              double background,
                                                              detect::ShiftedSumsForm form) override;
  std::optional<std::vector<detect::PhasePeak>> phaseCorrelations(
      const detect::PhaseCorrelationBatch& batch) override;
  std::optional<detect::SkyStack> skyStack(const FrameCube& cube, Velocity rate, double subtract,
                                           std::size_t first, std::size_t last) override;
  std::optional<calib::CosmicRayPreTestWords> cosmicRayPreTest(const FrameCube& cube, float thr) override;
  std::optional<std::vector<float>> filteredSnr(const detect::FilteredSnrInputs& in) override;
  stats::NoiseModel estimateNoiseModel(const FrameCube& zeroBiased, const Image& pixelSigma,
                                       const std::vector<std::uint8_t>& unmeasured,
                                       const stats::NoiseModelParams& params, CancelToken& cancel) override;
  stats::Background subtractPixelBackground(FrameCube& cube, const stats::BackgroundParams& params,
                                            const detect::MovingMask* exclude, ProgressSink& progress,
                                            CancelToken& cancel) override;
  bool zeroBias(FrameCube& cube, const pipeline::ZeroBiasInputs& in, pipeline::ZeroBiasResult& out,
                ProgressSink& progress, CancelToken& cancel) override;
  stack::MatchedFilterResult filterCube(FrameCube& cube, const stack::FilterKernel& kernel,
                                        ProgressSink& progress, CancelToken& cancel,
                                        const stats::NoiseModel* noise, std::uint64_t revision) override;
  stack::MatchedFilterResult filterCubeFrom(const FrameCube& source, FrameCube& filtered,
                                            const stack::FilterKernel& kernel, ProgressSink& progress,
                                            CancelToken& cancel, const stats::NoiseModel* noise,
                                            std::uint64_t revision) override;

 private:
  /// removeFrameBackgrounds, with `plan`'s pixel calibration applied on the device after the upload first
  /// when given.
  stats::FrameBackgrounds frameBackgrounds(FrameCube& cube, const stats::FrameBackgroundParams& params,
                                           ProgressSink& progress, CancelToken& cancel,
                                           const calib::CalibrationPlan* plan);

  /// The device buffers the per-pixel background leaves for zeroBias's next stages.
  struct KeptCube {
    DeviceBuffer<float> pix, sigma;
    DeviceBuffer<std::uint8_t> mask;
    bool hasMask = false;
  };

  /// stats::subtractPixelBackground; with `keep`, the zero-biased frames (and the mask and sigma) stay on

  /// stats::subtractPixelBackground; with `keep`, the zero-biased frames (and the mask and sigma) stay on
  /// the device in *keep and the host cube is not written.
  stats::Background pixelBackground(FrameCube& cube, const stats::BackgroundParams& params,
                                    const detect::MovingMask* exclude, ProgressSink& progress,
                                    CancelToken& cancel, KeptCube* keep);
  /// The matched filter of `cube`'s pixels (with its mask when `hasMask`) written into `dest` (which may be
  /// `cube`); `freshDest`: dest's pixels are (re)allocated here, on another thread while the device works.
  stack::MatchedFilterResult filter(const FrameCube& cube, bool hasMask, FrameCube& dest, bool freshDest,
                                    const stack::FilterKernel& kernel, ProgressSink& progress,
                                    CancelToken& cancel, const stats::NoiseModel* noise,
                                    std::uint64_t revision);

  /// The device part of estimateNoiseModel.
  stats::NoiseModel noiseModel(const FrameCube& zeroBiased, const Image& pixelSigma,
                               const std::vector<std::uint8_t>& unmeasured,
                               const stats::NoiseModelParams& params, CancelToken& cancel);
  /// f(); when it throws, the downloads running behind it finish first (a CPU fallback then has the host
  /// cubes to itself). A download's failure into the pipeline's own cube (st::Error: the frames are half
  /// written) is thrown instead; any other (a fresh destination's, which the CPU writes anew) leaves f's.
  template <class F>
  auto finishingCopiesOnError(F&& f) {
    try {
      return f();
    } catch (...) {
      if (std::exception_ptr e = m_copies.wait()) {
        try {
          std::rethrow_exception(e);
        } catch (const GpuError&) {  // a fresh destination's: f's exception stands
        } catch (...) {
          throw;  // half written frames: the run stops
        }
      }
      throw;
    }
  }
  /// Drops the kept frames (after their queued download, if any, is waited for).
  void forgetKept() {
    m_kept = DeviceBuffer<float>();
    m_keptData = nullptr;
    m_keptCopiedThere = false;
    m_keptShapeKey = 0;
  }
  /// m_kept holds `cube`'s frames: the same buffer and size, and either zeroBias queued (or finished) their
  /// download into it, or its sampled pixels give the key m_kept was left with (resident_cube.hpp cubeKey).
  bool keptIs(const FrameCube& cube) const {
    if (m_kept.size() == 0 || m_kept.size() != cube.pixels().size() || m_keptData != cube.pixels().data())
      return false;
    // A queued download's target holds (or will) the kept frames: its pixels are not read (the copy may be
    // writing them), its shape and frame times are.
    return m_keptCopiedThere ? m_keptShapeKey == cubeShapeKey(cube) : m_keptKey == cubeKey(cube);
  }

  /// m_res, once the constructor's thread has made it (made here if that thread failed).
  DeviceResources& resources() {
    if (m_warm.joinable()) m_warm.join();
    return ensureResources(m_res);
  }

  DeviceInfo m_device;
  std::unique_ptr<DeviceResources> m_res;
  /// prefetch()'s upload: the cube's identity, and its device copy once `ok`.
  struct Prefetch {
    std::jthread thread;
    DeviceBuffer<float> pix;
    DeviceBuffer<std::uint8_t> mask;
    const float* data = nullptr;
    std::size_t size = 0, maskSize = 0;
    std::uint64_t key = 0;
    bool ok = false;
    /// The pixels came from the frame backgrounds' frames, not an upload: only the mask's upload is in flight
    /// (a few ms when sparse; a mask over 1/64 set goes whole, ~110 ms for 1500 x 512^2). Set before the
    /// thread starts.
    bool keptFrames = false;
    /// The mask too is the device's (the frame backgrounds' with the hot pixels, maskedInAllFrames): no
    /// upload at all. Set before the thread starts.
    bool keptMask = false;
    /// `key` is cubeShapeKey, not cubeKey: the kept frames' download into the host cube was still running
    /// when the prefetch began (its pixels are not read until waitForHostFrames or finishHostCopies).
    bool shapeKeyOnly = false;
    std::atomic<bool> finished{false};  ///< the thread is done (ok or not): join() will not wait
    double seconds = 0.0;
    void join() {
      if (thread.joinable()) thread.join();
    }
    ~Prefetch() { join(); }
  };
  /// The prefetch when it is `cube`'s (same buffer and sizes), its upload done and its key still the cube's;
  /// else null (with !waitForUpload, also while the upload runs).
  std::shared_ptr<Prefetch> readyPrefetch(const FrameCube& cube, bool waitForUpload);
  /// Host -> device on stream `s` through `r`'s pinned staging buffers (pageable host memory). The host
  /// copies into the staging buffers on every core with `parallelCopy`, else on this thread only (the
  /// prefetch, which runs behind the CPU stages).
  static void stagedUpload(DeviceResources& r, void* dst, const void* src, std::size_t bytes, cudaStream_t s,
                           bool parallelCopy);
  /// A cube's mask: its non-zero bytes (found on every core) scattered into a zeroed device buffer when few
  /// (on stream `s`, done on return), else stagedUpload (`parallelCopy` as there).
  static void uploadMask(DeviceResources& r, std::uint8_t* dst, const std::uint8_t* src, std::size_t bytes,
                         cudaStream_t s, bool parallelCopy);
  std::unique_ptr<DeviceResources> m_prefetchRes;  // its own streams and staging: no contention with m_res
  std::shared_ptr<Prefetch> m_prefetch;            // after m_prefetchRes: joined before that is freed
  /// phaseCorrelations' device buffers, kept between its calls (a few per sky-rate iteration) and freed when
  /// the per-pixel background begins: at most a staging buffer's pairs, ~110 MB for 512^2 images.
  struct PhaseWorkspace {
    int width = 0, height = 0, nx = 0, ny = 0;
    std::size_t pairs = 0;  ///< the pairs the buffers hold
    DeviceBuffer<float2> twiddleX, twiddleY, spectra;
    DeviceBuffer<float> images, surface, rowMax;
    DeviceBuffer<int> rowArg;
    DeviceBuffer<double> peaks;
  };
  std::unique_ptr<PhaseWorkspace> m_phase;
  /// registrationLinks' device buffers, freed when the per-pixel background begins (as m_phase).
  struct RegistrationWorkspace {
    DeviceBuffer<float> samples, median, sigma, images, surface, rowMax;
    DeviceBuffer<float2> spectra, products;
    DeviceBuffer<int> rowArg;
    DeviceBuffer<double> rowSum, rowSum2, peaks;
  };
  std::unique_ptr<RegistrationWorkspace> m_registration;
  /// The noise model's variance map and reference sigma (stats::estimateNoiseModel of no frames), made on
  /// the host beside zeroBias's device stages, for the next estimateNoiseModel of the same inputs (their
  /// addresses, sizes, values' hash and the parameters).
  struct NoiseShape {
    stats::NoiseModel model;
    const float* sigma = nullptr;
    const std::uint8_t* unmeasured = nullptr;
    std::size_t sigmaSize = 0, unmeasuredSize = 0;
    std::uint64_t hash = 0;
    stats::NoiseModelParams params;
  };
  std::optional<NoiseShape> m_noiseShape;
  /// The hash NoiseShape keeps of the inputs.
  static std::uint64_t noiseShapeHash(const Image& pixelSigma, const std::vector<std::uint8_t>& unmeasured);
  // The frames removeFrameBackgrounds left on the device (its download's source), for prefetch() of the same
  // cube once the pipeline has said its pixels did not change since (framesUnchangedSinceFrameBackgrounds).
  // globalBackground and hotPixelExcess read them too, with the mask uploaded with them (freed once the hot
  // pixels are found: the pipeline then masks them).
  DeviceBuffer<float> m_sepFrames;
  DeviceBuffer<std::uint8_t> m_sepMask;
  /// m_sepMask is the host cube's mask: false from hotPixelExcess (the pipeline masks the hot pixels next)
  /// until maskedInAllFrames applies them.
  bool m_sepMaskCurrent = false;
  /// The pipeline said (maskedInAllFrames) that m_sepMask is the host's mask: the frame backgrounds' with the
  /// hot pixels and nothing else changed. Only then do registration and the prefetch take it instead of the
  /// host's (framesUnchangedSinceFrameBackgrounds allows other changes to the mask).
  bool m_sepMaskVouched = false;
  const float* m_sepFramesData = nullptr;
  bool m_sepFramesValid = false;
  /// allowFrameDownloadBehind: the frame backgrounds' download may run behind the stages after it.
  bool m_frameDownloadBehind = false;
  /// The host cube that download is writing (until finishHostCopies), and its frames' size in floats.
  const float* m_framesPendingData = nullptr;
  std::size_t m_framesPendingFramePixels = 0;
  /// `cube`'s pixels are that download's destination and it may still be writing them.
  bool framesPending(const FrameCube& cube) const {
    return m_framesPendingData != nullptr && m_framesPendingData == cube.pixels().data();
  }
  /// Forgets the frame backgrounds' frames and mask kept on the device, and what was said of them.
  void dropKeptFrames() {
    m_sepFrames = DeviceBuffer<float>();
    m_sepMask = DeviceBuffer<std::uint8_t>();
    m_sepFramesData = nullptr;
    m_sepFramesValid = false;
    m_sepMaskCurrent = m_sepMaskVouched = false;
  }
  /// The kept frames when the pipeline vouched that they are `cube`'s and the cube's mask is the size of the
  /// kept one (none or the same); else null.
  const float* keptFrames(const FrameCube& cube) const {
    return m_sepFramesValid && m_sepFramesData == cube.pixels().data() &&
                   m_sepFrames.size() == cube.pixels().size() && m_sepMaskCurrent &&
                   cube.mask().size() == m_sepMask.size()
               ? m_sepFrames.get()
               : nullptr;
  }
  std::string m_note;
  bool m_keepResident = true;
  // The frames zeroBias or removeResidualMeans wrote, kept for the noise model and the matched filter of the
  // same host cube.
  DeviceBuffer<float> m_kept;
  const float* m_keptData = nullptr;
  std::uint64_t m_keptKey = 0;
  bool m_keptCopiedThere = false;    ///< zeroBias queued m_kept's download into m_keptData
  std::uint64_t m_keptShapeKey = 0;  ///< then: cubeShapeKey of that cube
  /// Downloads behind the stages after them: zeroBias's zero-biased cube, the matched filter's frames.
  /// After m_kept and the cubes' buffers they read: finished before those are freed.
  HostCopies m_copies;
  std::jthread m_warm;  // last: joined before the members it writes are destroyed
};

}  // namespace st::gpu
