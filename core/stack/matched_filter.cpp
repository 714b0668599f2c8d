#include "st/stack/matched_filter.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <utility>
#include <vector>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#endif

#include "../common/opencv_threads.hpp"
#include "st/common/error.hpp"
#include "st/common/fftw_plans.hpp"
#include "st/common/parallel.hpp"
#include "st/stats/noise_model.hpp"
#include "st/stats/order_statistic.hpp"

namespace st::stack {
namespace {

constexpr std::size_t kMinNoiseSamples = 1000;
constexpr std::size_t kMinFrameSamples = 400;

// 1.4826 x the median absolute deviation of v (v is overwritten). maxThreads as stats::kthSmallest's: 1 for
// the per-frame samples, which filterNoiseFromSamples selects on every core at once.
double madSigma(std::vector<float>& v, unsigned maxThreads = 0) {
  if (v.empty()) return 0.0;
  const float med = stats::kthSmallest(v.data(), v.size(), v.size() / 2, maxThreads);
  for (auto& x : v)
    x = std::fabs(x - med);
  return 1.4826 * double(stats::kthSmallest(v.data(), v.size(), v.size() / 2, maxThreads));
}

/// Indices of up to maxFrames frames spread evenly over n frames.
std::vector<std::size_t> spreadFrames(std::size_t n, std::size_t maxFrames) {
  std::vector<std::size_t> idx;
  const std::size_t k = std::min(n, maxFrames);
  for (std::size_t i = 0; i < k; ++i)
    idx.push_back(i * n / k);
  return idx;
}

/// 1 where the input pixel is zero, masked or non-finite (after zeroing it), grown by `half` px, and along
/// the frame edges.
cv::Mat excludedPixels(float* frame, const std::uint8_t* mask, int width, int height, int half) {
  st::detail::useOpenCvSequentially();  // called on parallelFor's threads
  cv::Mat bad(height, width, CV_8U, cv::Scalar(0));
  for (int y = 0; y < height; ++y) {
    auto* row = bad.ptr<std::uint8_t>(y);
    for (int x = 0; x < width; ++x) {
      const std::size_t i = std::size_t(y) * width + x;
      row[x] = (frame[i] == 0.0f || (mask && mask[i])) ? 1 : 0;
    }
  }
  if (half > 0) {
    const cv::Mat se = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * half + 1, 2 * half + 1));
    cv::dilate(bad, bad, se, cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(1));
  }
  return bad;
}

/// The inverse-variance weights of the matched filter (matched_filter.hpp, filterCube): 1/v per pixel, and
/// per pixel the output scale sigma_ref sqrt(sum K^2) / sqrt(Phi), Phi = (K^2 conv omega), omega = (1/v) x
/// the mean over frames of [pixel used in frame n] / s_n^2.
// acc[x] += a where f[x] is a sample (non-zero, finite, unmasked): adding +0.0 elsewhere leaves acc[x] as it
// is, so the AVX2 path is the scalar test's sum exactly.
void addWhereSampledScalar(double* acc, const float* f, const std::uint8_t* m, double a, int x0, int w) {
  for (int x = x0; x < w; ++x)
    if (f[x] != 0.0f && std::isfinite(f[x]) && !(m && m[x])) acc[x] += a;
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define ST_MATCHED_FILTER_AVX2 1
__attribute__((target("avx2"))) void addWhereSampledAvx2(double* acc, const float* f, const std::uint8_t* m,
                                                         double a, int w) {
  const __m256d av = _mm256_set1_pd(a);
  const __m256 zero = _mm256_setzero_ps(), kMax = _mm256_set1_ps(std::numeric_limits<float>::max());
  const __m256 absMask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256i zi = _mm256_setzero_si256();
  int x = 0;
  for (; x + 8 <= w; x += 8) {
    const __m256 v = _mm256_loadu_ps(f + x);
    __m256 ok = _mm256_and_ps(_mm256_cmp_ps(v, zero, _CMP_NEQ_OQ),
                              _mm256_cmp_ps(_mm256_and_ps(v, absMask), kMax, _CMP_LE_OQ));
    if (m) {
      const __m128i m8 = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(m + x));
      ok = _mm256_and_ps(ok, _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_cvtepu8_epi32(m8), zi)));
    }
    // The 8 lanes' masks widened to 4 + 4 doubles.
    const __m256i oki = _mm256_castps_si256(ok);
    const __m256d lo = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm256_castsi256_si128(oki)));
    const __m256d hi = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm256_extracti128_si256(oki, 1)));
    _mm256_storeu_pd(acc + x, _mm256_add_pd(_mm256_loadu_pd(acc + x), _mm256_and_pd(av, lo)));
    _mm256_storeu_pd(acc + x + 4, _mm256_add_pd(_mm256_loadu_pd(acc + x + 4), _mm256_and_pd(av, hi)));
  }
  addWhereSampledScalar(acc, f, m, a, x, w);
}
#endif

void addWhereSampled(double* acc, const float* f, const std::uint8_t* m, double a, int w) {
#ifdef ST_MATCHED_FILTER_AVX2
  static const bool avx2 = __builtin_cpu_supports("avx2") != 0;
  if (avx2) return addWhereSampledAvx2(acc, f, m, a, w);
#endif
  addWhereSampledScalar(acc, f, m, a, 0, w);
}

struct Weights {
  std::vector<float> invVar;
  std::vector<float> outScale;
};

Weights makeWeights(const FrameCube& cube, const FilterKernel& kernel, const stats::NoiseModel& m,
                    CancelToken& cancel) {
  const int w = cube.width(), h = cube.height();
  const std::size_t np = cube.framePixels(), nf = cube.frameCount();
  if (m.variance.width != w || m.variance.height != h || m.frameScale.size() != nf)
    throw InputError("matched filter: the noise model (" + std::to_string(m.variance.width) + "x" +
                     std::to_string(m.variance.height) + ", " + std::to_string(m.frameScale.size()) +
                     " frames) does not match the cube (" + std::to_string(w) + "x" + std::to_string(h) +
                     ", " + std::to_string(nf) + " frames)");
  Weights out;
  out.invVar.resize(np);
  for (std::size_t i = 0; i < np; ++i) {
    const float v = m.variance.pixels[i];
    out.invVar[i] = v > 0.0f && std::isfinite(v) ? 1.0f / v : 0.0f;
  }
  std::vector<double> invS2(nf);
  for (std::size_t n = 0; n < nf; ++n)
    invS2[n] = 1.0 / (m.frameScale[n] * m.frameScale[n]);
  const bool hasMask = cube.mask().size() == cube.pixels().size();
  // Frames moved onto frame 0's grid by whole pixels (registration) cover only part of it: each pixel's
  // weight is averaged over the frames that cover it, so that a frame covering it is filtered to the same
  // noise as in a cube where all do (the search counts, in N_in, only the frames that saw a track position
  // once the frames are back on their own grids).
  const bool coverage = m.framesCovering.size() == np;
  cv::Mat omega(h, w, CV_32F);
  parallelFor(static_cast<std::size_t>(h), 8, [&](std::size_t y0, std::size_t y1) {
    std::vector<double> acc(static_cast<std::size_t>(w));
    for (std::size_t y = y0; y < y1; ++y) {
      cancel.throwIfCancelled();
      std::fill(acc.begin(), acc.end(), 0.0);
      for (std::size_t n = 0; n < nf; ++n) {
        const std::size_t off = n * np + y * w;
        addWhereSampled(acc.data(), cube.pixels().data() + off, hasMask ? cube.mask().data() + off : nullptr,
                        invS2[n], w);
      }
      auto* row = omega.ptr<float>(static_cast<int>(y));
      const std::uint32_t* covering = coverage ? m.framesCovering.data() + y * w : nullptr;
      for (int x = 0; x < w; ++x) {
        const double frames = covering ? std::max<double>(1.0, covering[x]) : static_cast<double>(nf);
        row[x] = static_cast<float>(acc[x] / frames * out.invVar[y * w + x]);
      }
    }
  });
  cv::Mat k2(kernel.kernel.height, kernel.kernel.width, CV_32F);
  for (int y = 0; y < k2.rows; ++y)
    for (int x = 0; x < k2.cols; ++x) {
      const float k = kernel.kernel.at(x, y);
      k2.at<float>(y, x) = k * k;
    }
  cv::Mat phi;
  cv::filter2D(omega, phi, CV_32F, k2, cv::Point(-1, -1), 0.0, cv::BORDER_CONSTANT);
  double phiMax = 0.0;
  cv::minMaxLoc(phi, nullptr, &phiMax);
  const double scale = m.sigmaRef * std::sqrt(kernel.sumSquares);
  out.outScale.resize(np);
  for (int y = 0; y < h; ++y) {
    const auto* row = phi.ptr<float>(y);
    for (int x = 0; x < w; ++x) {
      const double p = row[x];
      out.outScale[std::size_t(y) * w + x] =
          p > 1e-9 * phiMax ? static_cast<float>(scale / std::sqrt(p)) : 0.0f;
    }
  }
  return out;
}

}  // namespace

FilterKernel makeFilterKernel(const psf::Moffat& psf, double truncation) {
  if (!(truncation > 0.0 && truncation < 1.0))
    throw InputError("matched filter: truncation " + std::to_string(truncation) + " must be in (0, 1)");
  if (!(psf.radius > 0.0) || !(psf.beta > 1.0) || !std::isfinite(psf.radius) || !std::isfinite(psf.beta))
    throw InputError("matched filter: PSF with R = " + std::to_string(psf.radius) +
                     ", beta = " + std::to_string(psf.beta) + " is not usable (need R > 0, beta > 1)");
  const double rMax = psf.radiusAtFraction(truncation);
  FilterKernel k;
  k.halfSize = std::max(1, static_cast<int>(std::floor(rMax)));
  const int n = 2 * k.halfSize + 1;
  k.kernel = Image(n, n, 0.0f);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const double dx = x - k.halfSize, dy = y - k.halfSize;
      if (dx * dx + dy * dy > rMax * rMax) continue;
      const float v = static_cast<float>(psf.pixelMean(dx, dy, 4));
      k.kernel.at(x, y) = v;
      k.sum += v;
      k.sumSquares += double(v) * v;
    }
  return k;
}

namespace {

/// The padded FFT size for at least `minimum` samples: the smallest multiple of 16 whose other factors are
/// 2, 3, 5, 7 and 11 (FFTW's real transforms are fastest there: 528 took 3.4 ms where 520 took 3.9 and 525
/// 8.6 on the dev VM).
int goodFftSize(int minimum) {
  for (int n = std::max(16, (minimum + 15) / 16 * 16);; n += 16) {
    int m = n / 16;
    for (int p : {2, 3, 5, 7, 11})
      while (m % p == 0) m /= p;
    if (m == 1) return n;
  }
}

/// Convolution of width x height frames with one kernel by FFT (zero-padded to nx x ny >= frame + halfSize,
/// so the circular convolution equals the linear one with zeros outside the frame, which is what
/// cv::filter2D with BORDER_CONSTANT gave: the same sums in another order, equal to ~1e-6 of the values).
/// 7x faster than filter2D on 512^2 frames with a 17^2 kernel (3.4 vs 24 ms on the dev VM). The plans are
/// FFTW_ESTIMATE ones: FFTW_MEASURE was 30% faster but picks its algorithm by timing, so two runs of the same
/// cube could differ in the last bits (a batch's catalogue then differs from separate runs'). The kernel's
/// spectrum is made once and shared; each thread has its own Buffers.
class FftConvolver {
 public:
  FftConvolver(int width, int height, const FilterKernel& kernel)
      : m_w(width),
        m_h(height),
        m_nx(goodFftSize(width + kernel.halfSize)),
        m_ny(goodFftSize(height + kernel.halfSize)),
        m_plans(fftw::plans2d(m_nx, m_ny, false)),
        m_kernel(fftw::allocCplx(spectrumSize(), "matched filter")) {
    fftw::RealBuf r = fftw::allocReal(realSize(), "matched filter");
    std::fill(r.get(), r.get() + realSize(), 0.0f);
    const int half = kernel.halfSize, n = 2 * half + 1;
    const float norm = 1.0f / (static_cast<float>(m_nx) * static_cast<float>(m_ny));
    // The kernel centred on (0, 0) with wrap-around, mirrored: the FFT convolves, and this makes it the
    // correlation filter2D computed (the same for the point-symmetric Moffat kernel).
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const int px = (half - x + m_nx) % m_nx, py = (half - y + m_ny) % m_ny;
        r[static_cast<std::size_t>(py) * m_nx + px] = kernel.kernel.at(x, y) * norm;
      }
    fftwf_execute_dft_r2c(m_plans.forward, r.get(), m_kernel.get());
  }

  struct Buffers {
    fftw::RealBuf real;
    fftw::CplxBuf spectrum;
  };
  Buffers buffers() const {
    return {fftw::allocReal(realSize(), "matched filter"), fftw::allocCplx(spectrumSize(), "matched filter")};
  }

  /// Convolves `frame` (m_w x m_h, row-major) in place.
  void apply(float* frame, Buffers& b) const {
    float* r = b.real.get();
    for (int y = 0; y < m_h; ++y) {
      float* row = r + static_cast<std::size_t>(y) * m_nx;
      std::memcpy(row, frame + static_cast<std::size_t>(y) * m_w, sizeof(float) * m_w);
      std::fill(row + m_w, row + m_nx, 0.0f);
    }
    std::fill(r + static_cast<std::size_t>(m_h) * m_nx, r + realSize(), 0.0f);
    convolveInPlace(b);
    for (int y = 0; y < m_h; ++y)
      std::memcpy(frame + static_cast<std::size_t>(y) * m_w, r + static_cast<std::size_t>(y) * m_nx,
                  sizeof(float) * m_w);
  }

  /// The weighted filter of one frame in two passes over it instead of five: in goes the frame with
  /// non-finite and masked samples as 0, times inScale[i] * s (s: the frame's 1 / scale^2); out comes the
  /// filtered frame times outScale[i]. The same float operations as zeroing, `f[i] *= inScale[i] * s`,
  /// apply() and `f[i] *= outScale[i]` one after the other.
  void applyWeighted(float* frame, const std::uint8_t* mask, const float* inScale, float s, const float* outScale,
                     Buffers& b) const {
    float* r = b.real.get();
    for (int y = 0; y < m_h; ++y) {
      float* row = r + static_cast<std::size_t>(y) * m_nx;
      const std::size_t o = static_cast<std::size_t>(y) * m_w;
      weightRow(row, frame + o, mask ? mask + o : nullptr, inScale + o, s, m_w);
      std::fill(row + m_w, row + m_nx, 0.0f);
    }
    std::fill(r + static_cast<std::size_t>(m_h) * m_nx, r + realSize(), 0.0f);
    convolveInPlace(b);
    for (int y = 0; y < m_h; ++y) {
      const std::size_t o = static_cast<std::size_t>(y) * m_w;
      const float* row = r + static_cast<std::size_t>(y) * m_nx;
      for (int x = 0; x < m_w; ++x)
        frame[o + x] = row[x] * outScale[o + x];
    }
  }

 private:
  static void weightRow(float* out, const float* f, const std::uint8_t* m, const float* inScale, float s, int w) {
    const float kMax = std::numeric_limits<float>::max();
    if (m) {
      for (int x = 0; x < w; ++x) {
        const float v = (std::fabs(f[x]) <= kMax) & (m[x] == 0) ? f[x] : 0.0f;
        out[x] = v * (inScale[x] * s);
      }
    } else {
      for (int x = 0; x < w; ++x) {
        const float v = std::fabs(f[x]) <= kMax ? f[x] : 0.0f;
        out[x] = v * (inScale[x] * s);
      }
    }
  }

  void convolveInPlace(Buffers& b) const {
    float* r = b.real.get();
    fftwf_execute_dft_r2c(m_plans.forward, r, b.spectrum.get());
    fftwf_complex* c = b.spectrum.get();
    const fftwf_complex* k = m_kernel.get();
    for (std::size_t i = 0; i < spectrumSize(); ++i) {
      const float re = c[i][0] * k[i][0] - c[i][1] * k[i][1];
      const float im = c[i][0] * k[i][1] + c[i][1] * k[i][0];
      c[i][0] = re;
      c[i][1] = im;
    }
    fftwf_execute_dft_c2r(m_plans.inverse, c, r);
  }

 private:
  std::size_t realSize() const { return static_cast<std::size_t>(m_nx) * m_ny; }
  std::size_t spectrumSize() const { return static_cast<std::size_t>(m_nx / 2 + 1) * m_ny; }

  int m_w, m_h, m_nx, m_ny;
  fftw::PlanPair m_plans;
  fftw::CplxBuf m_kernel;
};

}  // namespace

void filterFrame(float* frame, int width, int height, const FilterKernel& kernel) {
  const FftConvolver conv(width, height, kernel);
  FftConvolver::Buffers b = conv.buffers();
  conv.apply(frame, b);
}

MatchedFilterResult filterCube(FrameCube& cube, const FilterKernel& kernel, ProgressSink& progress,
                               CancelToken& cancel, const stats::NoiseModel* noise) {
  const int w = cube.width(), h = cube.height();
  const std::size_t nFrames = cube.frameCount(), np = cube.framePixels();
  const bool hasMask = cube.mask().size() == cube.pixels().size();
  const bool weighted = noise && !noise->empty();
  const Weights weights = weighted ? makeWeights(cube, kernel, *noise, cancel) : Weights{};
  const std::vector<std::size_t> sampleFrames = filterNoiseFrames(nFrames);
  std::vector<std::vector<float>> samples(sampleFrames.size());
  std::atomic<std::size_t> done{0};
  progress.report(0.0, "matched filter");
  const FftConvolver conv(w, h, kernel);
  parallelFor(nFrames, 1, [&](std::size_t b, std::size_t e) {
    FftConvolver::Buffers buffers = conv.buffers();
    for (std::size_t n = b; n < e; ++n) {
      cancel.throwIfCancelled();
      float* f = cube.frame(n);
      const std::uint8_t* m = hasMask ? cube.mask().data() + n * np : nullptr;
      const auto slot = std::lower_bound(sampleFrames.begin(), sampleFrames.end(), n);
      const bool sampled = slot != sampleFrames.end() && *slot == n;
      if (weighted && !sampled) {
        // Zeroing, weights, filter and output scale fused (the same arithmetic as the steps below).
        const float invS2 = static_cast<float>(1.0 / (noise->frameScale[n] * noise->frameScale[n]));
        conv.applyWeighted(f, m, weights.invVar.data(), invS2, weights.outScale.data(), buffers);
        const std::size_t d = ++done;
        if (d % 16 == 0 || d == nFrames) progress.report(double(d) / double(nFrames), "matched filter");
        continue;
      }
      for (std::size_t i = 0; i < np; ++i)
        if (!std::isfinite(f[i]) || (m && m[i])) f[i] = 0.0f;
      cv::Mat bad;
      if (sampled) bad = excludedPixels(f, m, w, h, kernel.halfSize);
      if (weighted) {
        const float invS2 = static_cast<float>(1.0 / (noise->frameScale[n] * noise->frameScale[n]));
        for (std::size_t i = 0; i < np; ++i)
          f[i] *= weights.invVar[i] * invS2;
      }
      conv.apply(f, buffers);
      if (weighted)
        for (std::size_t i = 0; i < np; ++i)
          f[i] *= weights.outScale[i];
      if (sampled) {
        auto& out = samples[std::size_t(slot - sampleFrames.begin())];
        for (int y = kernel.halfSize; y < h - kernel.halfSize; y += 3) {
          const auto* row = bad.ptr<std::uint8_t>(y);
          for (int x = kernel.halfSize; x < w - kernel.halfSize; x += 3)
            if (!row[x]) out.push_back(f[std::size_t(y) * w + x]);
        }
      }
      const std::size_t d = ++done;
      if (d % 16 == 0 || d == nFrames) progress.report(double(d) / double(nFrames), "matched filter");
    }
  });
  return filterNoiseFromSamples(samples, kernel);
}

std::vector<std::size_t> filterNoiseFrames(std::size_t frameCount) {
  return spreadFrames(frameCount, 64);
}

MatchedFilterResult filterNoiseFromSamples(std::vector<std::vector<float>>& samples, const FilterKernel& kernel) {
  std::size_t total = 0;
  for (const auto& v : samples)
    total += v.size();
  if (total < kMinNoiseSamples)
    throw InputError("matched filter: only " + std::to_string(total) +
                     " unmasked pixels away from edges and zeroed regions to measure the filtered noise "
                     "sigma_F (need " +
                     std::to_string(kMinNoiseSamples) + "); the frames are mostly masked");
  MatchedFilterResult r;
  r.noiseSamples = total;
  // The search sums frames, so the sigma that scales a sum is the rms of the frames' sigmas, not the MAD of
  // the pooled pixels (smaller when frames differ in noise: a mixture of widths is heavy-tailed). Per frame
  // when every sampled frame has enough pixels, else pooled.
  const bool perFrame = std::all_of(samples.begin(), samples.end(),
                                    [](const std::vector<float>& v) { return v.size() >= kMinFrameSamples; });
  if (perFrame) {
    // The frames' sigmas on every core (serial, the 64 frames' medians were 46 ms of the GPU pipeline's
    // main thread for 1500 x 512^2), summed in frame order as before.
    std::vector<double> sigma(samples.size());
    parallelFor(samples.size(), 1, [&](std::size_t k0, std::size_t k1) {
      for (std::size_t k = k0; k < k1; ++k)
        sigma[k] = madSigma(samples[k], 1);
    });
    double sumSq = 0.0;
    for (const double s : sigma)
      sumSq += s * s;
    r.sigmaF = std::sqrt(sumSq / static_cast<double>(samples.size()));
  } else {
    std::vector<float> all;
    all.reserve(total);
    for (const auto& v : samples)
      all.insert(all.end(), v.begin(), v.end());
    r.sigmaF = madSigma(all);
  }
  r.kernelHalfSize = kernel.halfSize;
  r.kernelSumSquares = kernel.sumSquares;
  return r;
}

double measureFilteredNoise(const FrameCube& cube, int border, std::size_t maxFrames, int stride) {
  std::vector<float> all;
  const int w = cube.width(), h = cube.height();
  stride = std::max(1, stride);
  for (std::size_t n : spreadFrames(cube.frameCount(), maxFrames)) {
    const float* f = cube.frame(n);
    for (int y = border; y < h - border; y += stride)
      for (int x = border; x < w - border; x += stride) {
        const float v = f[std::size_t(y) * w + x];
        if (v != 0.0f && std::isfinite(v)) all.push_back(v);
      }
  }
  return all.size() < kMinNoiseSamples ? 0.0 : madSigma(all);
}

search::FilteredCube makeFilteredCube(FrameCube prepared, const psf::Moffat& psf, Velocity skyRate,
                                      ProgressSink& progress, CancelToken& cancel) {
  search::FilteredCube out;
  out.frames = std::move(prepared);
  const FilterKernel kernel = makeFilterKernel(psf);
  out.sigmaF = filterCube(out.frames, kernel, progress, cancel).sigmaF;
  out.skyRate = skyRate;
  out.psfFwhmPx = psf.fwhm();
  out.revision = search::nextCubeRevision();
  return out;
}

}  // namespace st::stack
