// The sky rate's chain's phase correlations on the device (issue 16: gpu/src/phase_correlation_kernels.cu,
// an FFT of our own) against the CPU's detect::detail::phaseShift (single-precision FFTW), the oracle: on
// compressed, Hanning-windowed star fields like the links', at whole and fractional offsets, at sizes that
// need no padding (512^2), padding (97 x 131 -> 100 x 135), radix-3 and radix-5 stages (243 x 250,
// 375 x 360) and rows of 6000 (more shared memory than a block has by default), the same offset within 1e-3 px and the same response within 1e-4 (the CPU-vs-OpenCV test's
// tolerances: two FFTs' float rounding apart). A pair whose surface is not finite (an infinite pixel) comes
// back not ok (the CPU correlates it), the others unchanged; sizes the kernels do not take and pairs larger than a staging
// buffer are declined; ST_GPU_PHASE_CORRELATIONS_ON_HOST=1 declines every batch. Skips without a device.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "../../core/detect/sky_rate_match.hpp"  // white-box: the CPU's phaseShift, the oracle
#include "require_gpu_preprocess.hpp"
#include "star_field_image.hpp"
#include "st/detect/sky_rate.hpp"

namespace st {
namespace {

struct Pair {
  cv::Mat a, b;
  double dx, dy;
};

// The batch of `pairs` as the chain makes it: the window times the image, as floats.
detect::PhaseCorrelationBatch batchOf(const std::vector<Pair>& pairs, const cv::Mat& window) {
  detect::PhaseCorrelationBatch batch;
  batch.width = pairs[0].a.cols;
  batch.height = pairs[0].a.rows;
  batch.nx = cv::getOptimalDFTSize(batch.width);
  batch.ny = cv::getOptimalDFTSize(batch.height);
  batch.pairs = pairs.size();
  batch.fill = [&pairs, &window](std::size_t p, float* a, float* b) {
    auto put = [&](const cv::Mat& m, float* out) {
      for (int y = 0; y < m.rows; ++y)
        for (int x = 0; x < m.cols; ++x)
          out[static_cast<std::size_t>(y) * m.cols + x] =
              static_cast<float>(window.empty() ? m.at<double>(y, x) : window.at<double>(y, x) * m.at<double>(y, x));
    };
    put(pairs[p].a, a);
    put(pairs[p].b, b);
  };
  return batch;
}

TEST(GpuPhaseCorrelation, EqualsTheCpusPhaseShift) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  unsetenv("ST_GPU_PHASE_CORRELATIONS_ON_HOST");
  struct Size {
    int w, h, pairs;
  };
  // 20 pairs of 512^2: a staging buffer's 16, then 4 (two chunks). 6000 x 24: rows of 6000 whose shared
  // memory with the peak's reduction arrays passes the default 48 KB a block.
  const Size sizes[] = {{512, 512, 20}, {97, 131, 4}, {243, 250, 4}, {375, 360, 3}, {6000, 24, 2}};
  const double offsets[][2] = {{3.0, -2.0}, {0.37, 1.61}, {-7.25, 4.5}, {0.0, 0.0}, {12.6, -5.1}};
  double worstD = 0.0, worstR = 0.0;
  unsigned seed = 1;
  for (const Size& sz : sizes) {
    SCOPED_TRACE(std::to_string(sz.w) + " x " + std::to_string(sz.h));
    std::vector<Pair> pairs;
    for (int k = 0; k < sz.pairs; ++k) {
      const double* o = offsets[k % 5];
      const int stars = std::max(20, sz.w * sz.h / 3000);
      pairs.push_back({test::starField(sz.w, sz.h, stars, 0.0, 0.0, seed),
                       test::starField(sz.w, sz.h, stars, o[0], o[1], seed), o[0], o[1]});
      ++seed;
    }
    cv::Mat window;
    cv::createHanningWindow(window, pairs[0].a.size(), CV_64F);
    const auto peaks = accel->phaseCorrelations(batchOf(pairs, window));
    ASSERT_TRUE(peaks.has_value()) << accel->lastNote();
    ASSERT_EQ(peaks->size(), pairs.size());
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      SCOPED_TRACE("pair " + std::to_string(k));
      double r = 0.0;
      const cv::Point2d d = detect::detail::phaseShift(pairs[k].a, pairs[k].b, window, &r);
      const detect::PhasePeak& g = (*peaks)[k];
      ASSERT_TRUE(g.ok);
      EXPECT_NEAR(g.dx, d.x, 1e-3);
      EXPECT_NEAR(g.dy, d.y, 1e-3);
      EXPECT_NEAR(g.response, r, 1e-4);
      // The stars' offset, to the 5 x 5 centroid's accuracy (0.58 px off at worst on these small fields, on
      // the CPU as on the device): the peak is the stars'.
      if (std::min(sz.w, sz.h) >= 64) {  // (the 24-row strip's window leaves too few rows to insist)
        EXPECT_NEAR(g.dx, pairs[k].dx, 1.0);
        EXPECT_NEAR(g.dy, pairs[k].dy, 1.0);
      }
      worstD = std::max({worstD, std::fabs(g.dx - d.x), std::fabs(g.dy - d.y)});
      worstR = std::max(worstR, std::fabs(g.response - r));
    }
  }
  std::printf("device vs CPU phase correlation: worst offset difference %.3g px, worst response difference %.3g\n",
              worstD, worstR);
  std::printf("%s\n", accel->lastNote().c_str());
}

TEST(GpuPhaseCorrelation, ANonFinitePairIsLeftToTheCpuAndUnsupportedBatchesAreDeclined) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  unsetenv("ST_GPU_PHASE_CORRELATIONS_ON_HOST");
  std::vector<Pair> pairs;
  for (unsigned k = 0; k < 3; ++k)
    pairs.push_back({test::starField(128, 128, 30, 0.0, 0.0, 40 + k), test::starField(128, 128, 30, 2.5, -1.5, 40 + k),
                     2.5, -1.5});
  // An infinite pixel: its rows' and columns' spectra infinite, the normalised cross power NaN, the surface
  // NaN. A NaN pixel: NaN spectra, whose normalisation gives 0 (m > 0 is false) on both, so a finite (zero)
  // surface and the CPU's answer for it.
  pairs[1].a.at<double>(60, 60) = std::numeric_limits<double>::infinity();
  pairs[2].b.at<double>(30, 90) = std::numeric_limits<double>::quiet_NaN();
  const auto peaks = accel->phaseCorrelations(batchOf(pairs, cv::Mat()));
  ASSERT_TRUE(peaks.has_value());
  ASSERT_EQ(peaks->size(), 3u);
  EXPECT_TRUE((*peaks)[0].ok);
  EXPECT_FALSE((*peaks)[1].ok);
  EXPECT_TRUE((*peaks)[2].ok);
  for (std::size_t k : {std::size_t{0}, std::size_t{2}}) {
    double r = 0.0;
    const cv::Point2d d = detect::detail::phaseShift(pairs[k].a, pairs[k].b, cv::Mat(), &r);
    EXPECT_NEAR((*peaks)[k].dx, d.x, 1e-3);
    EXPECT_NEAR((*peaks)[k].dy, d.y, 1e-3);
    EXPECT_NEAR((*peaks)[k].response, r, 1e-4);
  }
  // A transform size with a factor 7 (never cv::getOptimalDFTSize's), and pairs over a staging buffer
  // (2049 x 2048: 2 x 16.8 MB): declined before any image is asked for.
  int filled = 0;
  detect::PhaseCorrelationBatch odd;
  odd.width = odd.height = 14;
  odd.nx = odd.ny = 14;
  odd.pairs = 1;
  odd.fill = [&](std::size_t, float*, float*) { ++filled; };
  EXPECT_FALSE(accel->phaseCorrelations(odd).has_value());
  detect::PhaseCorrelationBatch large = odd;
  large.width = 2049;
  large.nx = 2160;  // 2^4 3^3 5
  large.height = large.ny = 2048;
  EXPECT_FALSE(accel->phaseCorrelations(large).has_value());
  EXPECT_EQ(filled, 0);
  // The benchmark knob leaves every batch to the CPU.
  setenv("ST_GPU_PHASE_CORRELATIONS_ON_HOST", "1", 1);
  EXPECT_FALSE(accel->phaseCorrelations(batchOf(pairs, cv::Mat())).has_value());
  unsetenv("ST_GPU_PHASE_CORRELATIONS_ON_HOST");
  EXPECT_TRUE(accel->phaseCorrelations(batchOf(pairs, cv::Mat())).has_value());
}

}  // namespace
}  // namespace st
