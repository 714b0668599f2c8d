#pragma once
// Plain parameter structs of the pre-processing kernels (gpu/src/preprocess_kernels.cu), C++17, no core
// headers. All pointers are device pointers; cube indices are frame-major, W*H floats per frame.
#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

namespace st::gpu {

/// The largest matched-filter kernel half size on the device (constant memory); larger kernels fall back
/// to the CPU.
inline constexpr int kMaxFilterHalf = 24;

/// Per-pixel background (stats::subtractPixelBackground).
struct BackgroundLaunch {
  float* pix;                  ///< the cube, nf frames; frames are made zero-biased in place
  const std::uint8_t* mask;    ///< nf frames of 1 = masked, or null
  float* buf;                  ///< nk frames: the samples of the used frames, NaN where left out
  const int* usedFrames;       ///< [nk] indices of the frames used (evenly spaced)
  const std::uint8_t* canvas;  ///< exclude mask at t_ref (cw x ch, 1 = excluded), or null
  const int* canvasShiftX;     ///< [nf] the exclude mask's shift of frame n
  const int* canvasShiftY;
  int canvasX0, canvasY0, canvasW, canvasH;
  int width, height;
  int nf, nk;
  /// samples above the pixel's own lower median + this are left out (strongSignalXi x global sigma;
  /// stats/strong_signal_cut.cpp cutStrongAboveMedian)
  double strongOffset;
  double xi;
  std::size_t minSamples;
  double globalMean, globalSigma;
  // outputs of the clip, per pixel
  float* level;
  float* sigma;
  std::uint8_t* valid;
  double* hi;
  // the subtraction
  const int* winLo;  ///< [nf] used frames [winLo, winHi) inside frame n's window (window > 0)
  const int* winHi;
  int window;  ///< 0: one mean per pixel
};

void launchBackgroundPrepare(const BackgroundLaunch& p, cudaStream_t s);
void launchBackgroundStrongCut(const BackgroundLaunch& p, cudaStream_t s);
void launchBackgroundClip(const BackgroundLaunch& p, cudaStream_t s);
void launchBackgroundSubtract(const BackgroundLaunch& p, cudaStream_t s);

/// Matched filter (stack::filterCube).
struct FilterLaunch {
  const float* in;           ///< input frames (zero-biased)
  const std::uint8_t* mask;  ///< 1 = masked (input taken as 0), or null
  float* out;                ///< filtered frames
  int width, height;
  int f0, f1;             ///< frames of this launch
  int half;               ///< kernel half size (<= kMaxFilterHalf); the kernel is in constant memory
  const float* invVar;    ///< weighted: 1/v per pixel, else null
  const float* invS2;     ///< weighted: [nf] 1/s_n^2 (float)
  const float* outScale;  ///< weighted: per-pixel output scale, else null
};

/// Copies the (2 half + 1)^2 kernel (row-major) to constant memory.
void setFilterKernel(const float* kernel, int half, cudaStream_t s);
void launchFilter(const FilterLaunch& p, cudaStream_t s);
/// Whether launchFilter runs a kernel of this half size with 4 outputs a thread (half 1-12, unless
/// ST_GPU_FILTER_PLAIN=1), else one output a thread; the same bits either way.
bool filterRegisterBlocked(int half);

/// omega(q) = invVar(q) x mean over frames of [q used in frame n] / s_n^2 (stack::filterCube's weights); the
/// mean is over covering[q] frames (at least 1) when `covering` is given (NoiseModel::framesCovering), else
/// over all nf.
void launchOmega(const float* pix, const std::uint8_t* mask, const double* invS2, const float* invVar,
                 const std::uint32_t* covering, float* omega, int width, int height, int nf, cudaStream_t s);

/// sigma_F samples of frame n: the filtered value at every 3rd pixel (x, y >= half, < size - half) or NaN
/// where an input pixel within +-half is zero, masked or non-finite. out: rows ny x nx.
void launchNoiseSamples(const float* in, const std::uint8_t* mask, const float* filtered, int width,
                        int height, int n, int half, float* out, int nx, int ny, cudaStream_t s);

}  // namespace st::gpu
