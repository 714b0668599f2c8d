// The sky rate's phase correlation (core/detect/sky_rate_match.cpp, single-precision FFTW) against its
// oracle, OpenCV's cv::phaseCorrelate in double precision: the same offset within 2e-3 px and the same
// response within 1e-4 on star fields like the sky rate's (thresholded and compressed, Hanning-windowed),
// at whole and fractional offsets, at sizes OpenCV pads (odd sizes) and does not, and without a window.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "../../core/detect/sky_rate_match.hpp"  // white-box: the internal phaseShift
#include "star_field_image.hpp"

namespace st {
namespace {

using test::starField;

struct Case {
  int w, h;
  double dx, dy;
  bool window;
};

TEST(SkyRatePhaseShift, EqualsOpenCvsPhaseCorrelate) {
  const Case cases[] = {
      {512, 512, 3.0, -2.0, true}, {512, 512, 7.4, 0.35, true}, {512, 512, -20.6, 11.2, true},
      {300, 200, 1.25, 4.5, true}, {257, 131, -3.3, 2.7, true}, {1432, 1370, 12.6, -5.1, true},
      {512, 512, 0.0, 0.0, true},  {128, 128, 2.5, 2.5, false}, {333, 97, -1.7, 0.2, false},
  };
  unsigned seed = 1;
  for (const Case& c : cases) {
    SCOPED_TRACE(std::to_string(c.w) + " x " + std::to_string(c.h) + " offset (" + std::to_string(c.dx) +
                 ", " + std::to_string(c.dy) + ")" + (c.window ? " windowed" : ""));
    const int stars = std::max(20, c.w * c.h / 3000);
    const cv::Mat a = starField(c.w, c.h, stars, 0.0, 0.0, seed);
    const cv::Mat b = starField(c.w, c.h, stars, c.dx, c.dy, seed);
    ++seed;
    cv::Mat window;
    if (c.window) cv::createHanningWindow(window, a.size(), CV_64F);
    const cv::Mat a0 = a.clone(), b0 = b.clone();
    double rOurs = 0.0, rCv = 0.0;
    const cv::Point2d ours = detect::detail::phaseShift(a, b, window, &rOurs);
    const cv::Point2d cv = cv::phaseCorrelate(a.clone(), b.clone(), window, &rCv);
    EXPECT_NEAR(ours.x, cv.x, 2e-3);
    EXPECT_NEAR(ours.y, cv.y, 2e-3);
    EXPECT_NEAR(rOurs, rCv, 1e-4);
    // The offset is the stars' (b relative to a), to the correlation's sub-pixel accuracy.
    EXPECT_NEAR(ours.x, c.dx, 0.5);
    EXPECT_NEAR(ours.y, c.dy, 0.5);
    EXPECT_GT(rOurs, 0.02);
    // The inputs are left as they were.
    EXPECT_EQ(cv::norm(a, a0, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(b, b0, cv::NORM_INF), 0.0);
  }
}

// Unrelated images: a response as low as OpenCV's, well below that of the same field moved.
TEST(SkyRatePhaseShift, UnrelatedImagesGiveALowResponseAsOpenCvs) {
  const cv::Mat a = starField(256, 256, 40, 0.0, 0.0, 11), b = starField(256, 256, 40, 0.0, 0.0, 12);
  const cv::Mat moved = starField(256, 256, 40, 3.0, 2.0, 11);
  cv::Mat window;
  cv::createHanningWindow(window, a.size(), CV_64F);
  double rOurs = 0.0, rCv = 0.0, rMoved = 0.0;
  detect::detail::phaseShift(a, b, window, &rOurs);
  cv::phaseCorrelate(a.clone(), b.clone(), window, &rCv);
  detect::detail::phaseShift(a, moved, window, &rMoved);
  EXPECT_NEAR(rOurs, rCv, 1e-4);
  EXPECT_LT(rOurs, 0.5 * rMoved);
  // Empty images: zero response, no NaN.
  const cv::Mat z = cv::Mat::zeros(64, 64, CV_64F);
  double rz = -1.0;
  const cv::Point2d d = detect::detail::phaseShift(z, z, cv::Mat(), &rz);
  EXPECT_EQ(rz, 0.0);
  EXPECT_TRUE(std::isfinite(d.x) && std::isfinite(d.y));
}

// The cross-power spectrum's vectorised normalisation (AVX2 where the CPU has it) against the scalar loop,
// bit for bit: random spectra with vanishing products (a zero bin in either), signed zeros, tiny and huge
// values, at lengths that leave a scalar tail.
TEST(SkyRatePhaseShift, VectorisedNormalisationEqualsTheScalarLoopBitForBit) {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
  if (!__builtin_cpu_supports("avx2")) GTEST_SKIP() << "no AVX2 here: both calls would run the scalar loop";
#else
  GTEST_SKIP() << "no AVX2 path on this architecture";
#endif
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::uniform_int_distribution<int> kind(0, 9), e(-30, 30);
  for (const std::size_t n :
       {std::size_t{1}, std::size_t{4}, std::size_t{7}, std::size_t{131}, std::size_t{257 * 512}}) {
    std::vector<float> fa(2 * n), fb(2 * n);
    for (std::size_t i = 0; i < 2 * n; ++i) {
      const int k = kind(rng);
      fa[i] = k == 0 ? 0.0f : k == 1 ? -0.0f : std::ldexp(u(rng), e(rng));
      fb[i] = k == 2 ? 0.0f : std::ldexp(u(rng), e(rng));
    }
    for (std::size_t i = 0; i < n; i += 5)  // whole bins of zeros in one spectrum or the other
      (i % 2 ? fa : fb)[2 * i] = 0.0f, (i % 2 ? fa : fb)[2 * i + 1] = 0.0f;
    for (std::size_t i = 3; i < 2 * n; i += 97)  // subnormal floats
      fa[i] = std::ldexp(u(rng), -140);
    const std::size_t special = n > 40 ? 40 : 0;  // non-finite bins (none come out of an FFT of finite data)
    if (special > 0) {
      fa[2 * special] = std::numeric_limits<float>::infinity();
      fb[2 * special + 3] = -std::numeric_limits<float>::infinity();
      fa[2 * special + 7] = std::numeric_limits<float>::quiet_NaN();
    }
    std::vector<float> scalar = fa, vectorised = fa;
    detect::detail::normaliseCrossPower(reinterpret_cast<float(*)[2]>(scalar.data()),
                                        reinterpret_cast<const float(*)[2]>(fb.data()), n, false);
    detect::detail::normaliseCrossPower(reinterpret_cast<float(*)[2]>(vectorised.data()),
                                        reinterpret_cast<const float(*)[2]>(fb.data()), n, true);
    EXPECT_EQ(std::memcmp(scalar.data(), vectorised.data(), scalar.size() * sizeof(float)), 0) << "n " << n;
    // Unit magnitude where the product does not vanish, 0 where it does (finite bins).
    for (std::size_t i = 0; i < n; ++i) {
      if (special > 0 && i >= special && i <= special + 3) continue;
      const double m = std::hypot(scalar[2 * i], scalar[2 * i + 1]);
      EXPECT_TRUE(m == 0.0 || std::fabs(m - 1.0) < 1e-6) << i << ": " << m;
    }
  }
}

// The row-order scan phaseShift used to find its peak: the first maximum in row order, of equal values the
// one first in the quadrant-swapped order.
std::size_t rowOrderScan(const std::vector<float>& c, int nx, int ny) {
  auto shiftedIndex = [&](std::size_t i) {
    const int x = static_cast<int>(i % static_cast<std::size_t>(nx)), y = static_cast<int>(i / nx);
    return static_cast<std::size_t>((y + ny / 2) % ny) * nx + static_cast<std::size_t>((x + nx / 2) % nx);
  };
  std::size_t bestAt = 0, bestShifted = shiftedIndex(0);
  for (std::size_t i = 1; i < c.size(); ++i) {
    if (c[i] < c[bestAt]) continue;
    if (c[i] > c[bestAt] || shiftedIndex(i) < bestShifted) bestAt = i, bestShifted = shiftedIndex(i);
  }
  return bestShifted;
}

// The peak search (largest value, then the first of its ties in the swapped order) against that scan: one
// peak, many ties (values on a coarse grid), signed zeros only, at even and odd sizes; and with NaN or
// infinite values, where it falls back to the scan itself.
TEST(SkyRatePhaseShift, PeakSearchEqualsTheRowOrderScan) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::uniform_int_distribution<int> coarse(-3, 3);
  const int sizes[][2] = {{512, 512}, {9, 7}, {64, 33}, {1, 5}, {6, 1}};
  for (const auto& sz : sizes) {
    const int nx = sz[0], ny = sz[1];
    const std::size_t n = static_cast<std::size_t>(nx) * ny;
    for (int variant = 0; variant < 5; ++variant) {
      std::vector<float> c(n);
      for (std::size_t i = 0; i < n; ++i)
        c[i] = variant == 0   ? u(rng)
               : variant == 1 ? static_cast<float>(coarse(rng))
               : variant == 2 ? ((i % 3) ? 0.0f : -0.0f)
                              : u(rng);
      if (variant == 3) c[n / 2] = std::numeric_limits<float>::quiet_NaN();
      if (variant == 4) c[n / 3] = std::numeric_limits<float>::infinity();
      SCOPED_TRACE(std::to_string(nx) + " x " + std::to_string(ny) + " variant " + std::to_string(variant));
      EXPECT_EQ(detect::detail::firstLargestShifted(c.data(), nx, ny), rowOrderScan(c, nx, ny));
    }
  }
}

// sourcesOf as it was, on OpenCV's labels: the oracle for the sparse union-find, order included (what is
// summed over the sources later is summed in their order).
std::vector<detect::detail::Source> sourcesByLabels(const cv::Mat& image, double minPeak) {
  cv::Mat labels;
  const int n = cv::connectedComponents(image > 0.0, labels, 8, CV_32S);
  std::vector<detect::detail::Source> acc(static_cast<std::size_t>(std::max(0, n)));
  std::vector<double> sw(acc.size(), 0.0);
  std::vector<int> pixels(acc.size(), 0);
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x) {
      const int l = labels.at<int>(y, x);
      if (l <= 0) continue;
      const double v = image.at<double>(y, x);
      auto& s = acc[static_cast<std::size_t>(l)];
      s.x += v * x, s.y += v * y, s.peak = std::max(s.peak, v);
      sw[static_cast<std::size_t>(l)] += v;
      ++pixels[static_cast<std::size_t>(l)];
    }
  std::vector<detect::detail::Source> out;
  for (std::size_t k = 1; k < acc.size(); ++k)
    if (pixels[k] >= 4 && acc[k].peak >= minPeak && sw[k] > 0)
      out.push_back({acc[k].x / sw[k], acc[k].y / sw[k], acc[k].peak});
  return out;
}

// The sources of thresholded images equal those of OpenCV's labels bit for bit and in the same order: star
// fields, random blobs of every shape (diagonal touches, U shapes that merge late, single pixels, the
// edges), at even and odd sizes, and an empty image.
TEST(SkyRatePhaseShift, SourcesEqualOpenCvsLabelsInTheirOrder) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<cv::Mat> images;
  images.push_back(starField(512, 512, 90, 0.0, 0.0, 3));
  images.push_back(starField(257, 131, 40, 1.5, -2.0, 4));
  for (const cv::Size size :
       {cv::Size(64, 64), cv::Size(63, 47), cv::Size(1, 9), cv::Size(9, 1), cv::Size(200, 3)})
    for (const double fill : {0.05, 0.3, 0.55}) {
      cv::Mat m = cv::Mat::zeros(size, CV_64F);
      for (int y = 0; y < m.rows; ++y)
        for (int x = 0; x < m.cols; ++x)
          if (u(rng) < fill) m.at<double>(y, x) = 0.1 + 3.0 * u(rng);
      images.push_back(m);
    }
  cv::Mat shapes = cv::Mat::zeros(16, 16, CV_64F);  // a U that joins at its bottom, a diagonal chain
  for (int y = 1; y < 8; ++y)
    shapes.at<double>(y, 2) = shapes.at<double>(y, 6) = 1.0 + y;
  for (int x = 2; x <= 6; ++x)
    shapes.at<double>(8, x) = 2.0;
  for (int k = 0; k < 6; ++k)
    shapes.at<double>(9 + k % 6, 9 + k) = 3.0;
  shapes.at<double>(0, 15) = shapes.at<double>(1, 14) = shapes.at<double>(0, 13) = shapes.at<double>(1, 12) =
      5.0;
  images.push_back(shapes);
  images.push_back(cv::Mat::zeros(32, 32, CV_64F));
  int compared = 0;
  for (std::size_t i = 0; i < images.size(); ++i)
    for (const double minPeak : {0.0, detect::detail::minPeakCompressed()}) {
      SCOPED_TRACE("image " + std::to_string(i) + " min peak " + std::to_string(minPeak));
      const auto ours = detect::detail::sourcesOf(images[i], minPeak);
      const auto ref = sourcesByLabels(images[i], minPeak);
      ASSERT_EQ(ours.size(), ref.size());
      for (std::size_t k = 0; k < ours.size(); ++k) {
        EXPECT_EQ(ours[k].x, ref[k].x) << k;
        EXPECT_EQ(ours[k].y, ref[k].y) << k;
        EXPECT_EQ(ours[k].peak, ref[k].peak) << k;
      }
      compared += static_cast<int>(ref.size());
    }
  EXPECT_GT(compared, 200);  // the test saw many sources
}

}  // namespace
}  // namespace st
