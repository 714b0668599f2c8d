#pragma once
// Test cubes for the GPU tests: white noise (sigma 1) on an uneven cadence with a gap, two frames out of
// time order, and point sources moving at constant velocity (IPSA's integer rounding, so a source sits at
// one pixel per frame and a search at its velocity sums it exactly). Also the device-or-skip helper.
#include <gtest/gtest.h>

#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "cuda_bench_options.hpp"
#include "st/gpu/cuda_backend.hpp"
#include "st/search/ipsa.hpp"
#include "st/search/types.hpp"

namespace st::test {

struct MovingPoint {
  int x = 0;  ///< position at t_ref, px
  int y = 0;
  Velocity v;        ///< px/s
  float amp = 1.0f;  ///< per frame, in units of the noise
};

struct CubeTiming {
  double cadenceS = 0.1;  ///< nominal frame spacing
  double jitterS = 0.03;  ///< uniform jitter of each mid-time, +-
  int gapAfter = 0;       ///< frames after this index come `gapS` later
  double gapS = 0.0;
  std::pair<int, int> swapped{1, 4};  ///< two frames stored out of time order
};

/// A w x h x n cube as described at the top of the file, PSF FWHM `fwhm` (for the record only).
inline search::FilteredCube movingPointsCube(int w, int h, int n, unsigned seed, const CubeTiming& timing,
                                             const std::vector<MovingPoint>& sources, double fwhm) {
  search::FilteredCube c;
  c.frames = FrameCube(w, h, static_cast<std::size_t>(n));
  c.sigmaF = 1.0;
  c.psfFwhmPx = fwhm;
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  std::uniform_real_distribution<double> jitter(-timing.jitterS, timing.jitterS);
  for (auto& p : c.frames.pixels())
    p = noise(rng);
  for (int k = 0; k < n; ++k) {
    const double t = timing.cadenceS * k + jitter(rng) + (k > timing.gapAfter ? timing.gapS : 0.0);
    c.frames.info()[k].mjdMid = 60000.0 + t / kSecondsPerDay;
  }
  std::swap(c.frames.info()[timing.swapped.first], c.frames.info()[timing.swapped.second]);
  const std::vector<double> dt = c.frames.timeOffsetsS();
  for (const MovingPoint& s : sources) {
    for (int k = 0; k < n; ++k) {
      const int x = s.x + search::ipsaShift(s.v.vx, dt[k]);
      const int y = s.y + search::ipsaShift(s.v.vy, dt[k]);
      if (x >= 0 && y >= 0 && x < w && y < h) c.frames.frame(k)[static_cast<std::size_t>(y) * w + x] += s.amp;
    }
  }
  return c;
}

/// The CUDA backend with `options` (and benchmark knobs, gpu/src/cuda_bench_options.hpp), or null when no
/// device is usable.
inline std::unique_ptr<gpu::CudaSearchBackend> cudaOrNull(const gpu::CudaOptions& options = {},
                                                          const gpu::CudaBenchOptions& bench = {}) {
  std::string whyNot;
  return gpu::makeCudaBenchBackend(whyNot, options, bench);
}

}  // namespace st::test

/// Declares `var` as the CUDA backend (options optional) or skips the test when there is no device.
#define ST_REQUIRE_GPU(var, ...)                \
  auto var = st::test::cudaOrNull(__VA_ARGS__); \
  if (!var) GTEST_SKIP() << "no usable CUDA device";
