// Registration's sampled links on the device (issue 16: CudaPreprocess::registrationLinks, from the frames
// the frame backgrounds kept there) against the CPU's own links (white-box: detect::detail::measureLink on
// the same host cube, the oracle): drifting star fields with noise, NaN samples and a mask of hot pixels
// and masked blocks, at 512^2 (the paper's frames, binned 1) and 1200 x 640 (binned 2 to 600 x 320: radices
// 4, 2, 3 and 5). Each pair's step within 1e-3 binned px and its significance within 1e-4 relative (the
// transforms' floats differ from FFTW's by rounding; the star images are the CPU's). A size the transform
// does not take (a prime factor of 7) and frames the device did not keep are declined (none: the CPU
// measures them). Through measureRegistration, the long sequence's 64 sampled links all come from the device
// with the CPU's model. Every test skips without a device.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include "../../core/detect/registration_links.hpp"  // white-box: the CPU's links, the oracle
#include "require_gpu_preprocess.hpp"
#include "st/common/progress.hpp"
#include "st/detect/registration.hpp"
#include "st/gpu/preprocess.hpp"
#include "st/stats/background.hpp"

namespace st {
namespace {

/// A star field drifting (0.8, -0.45) px per frame at 0.1 s a frame: 150 Gaussian stars (sigma 1.2 px) on
/// a sky of 100 with noise 5, 1 sample in 2000 NaN; with `masked`, 30 hot pixels masked in every frame and a
/// 20 x 20 block in every third.
FrameCube starField(int w, int h, int n, unsigned seed, bool masked) {
  FrameCube c(w, h, static_cast<std::size_t>(n));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<float> g(0.0f, 5.0f);
  struct Star {
    double x, y, flux;
  };
  std::vector<Star> stars;
  for (int k = 0; k < 150; ++k)
    stars.push_back({u(rng) * (w + 200) - 100, u(rng) * (h + 200) - 100, 300.0 + 5000.0 * u(rng) * u(rng)});
  if (masked) c.mask().assign(c.pixels().size(), 0);
  std::vector<std::size_t> hot;
  for (int k = 0; k < 30; ++k)
    hot.push_back(static_cast<std::size_t>(u(rng) * w * h));
  for (int f = 0; f < n; ++f) {
    c.info()[f].mjdMid = 60000.0 + 0.1 * f / 86400.0;
    float* px = c.frame(f);
    for (std::size_t i = 0; i < c.framePixels(); ++i)
      px[i] = 100.0f + g(rng);
    for (const Star& s : stars) {
      const double sx = s.x + 0.8 * f, sy = s.y - 0.45 * f;
      for (int y = static_cast<int>(sy) - 5; y <= static_cast<int>(sy) + 5; ++y)
        for (int x = static_cast<int>(sx) - 5; x <= static_cast<int>(sx) + 5; ++x) {
          if (x < 0 || y < 0 || x >= w || y >= h) continue;
          const double r2 = (x - sx) * (x - sx) + (y - sy) * (y - sy);
          px[static_cast<std::size_t>(y) * w + x] +=
              static_cast<float>(s.flux / (2 * M_PI * 1.44) * std::exp(-r2 / 2.88));
        }
    }
    for (std::size_t i = 0; i < c.framePixels(); ++i)
      if (u(rng) < 0.0005) px[i] = std::numeric_limits<float>::quiet_NaN();
    if (masked) {
      std::uint8_t* m = c.mask().data() + static_cast<std::size_t>(f) * c.framePixels();
      for (const std::size_t i : hot)
        m[i] = 1;
      if (f % 3 == 0)
        for (int y = 100; y < 120; ++y)
          for (int x = 200; x < 220; ++x)
            m[static_cast<std::size_t>(y) * w + x] = 1;
    }
  }
  return c;
}

detect::RegistrationLinkBatch batchOf(const detect::detail::StarImages& images,
                                      const std::vector<std::pair<std::size_t, std::size_t>>& pairs) {
  detect::RegistrationLinkBatch b;
  b.bin = images.bin();
  b.width = images.width();
  b.height = images.height();
  b.taperX = &images.weights().taperX;
  b.taperY = &images.weights().taperY;
  b.highPass = &images.weights().highPass;
  b.pairs = pairs;
  return b;
}

TEST(GpuRegistrationLinks, EqualTheCpusLinks) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  struct Case {
    int w, h;
    bool masked;
  };
  for (const Case& k : {Case{512, 512, false}, Case{512, 512, true}, Case{1200, 640, true}}) {
    FrameCube cube = starField(k.w, k.h, 12, 5, k.masked);
    NullProgress progress;
    CancelToken cancel;
    accel->removeFrameBackgrounds(cube, {}, progress, cancel);
    accel->framesUnchangedSinceFrameBackgrounds(cube, true);
    const detect::detail::StarImages images(cube);
    // Neighbours, a long gap (less overlap, a weaker peak), a frame against itself and a repeated frame.
    const std::vector<std::pair<std::size_t, std::size_t>> pairs{{1, 0},  {2, 1}, {7, 3},
                                                                 {11, 0}, {5, 5}, {6, 1}};
    const auto peaks = accel->registrationLinks(cube, batchOf(images, pairs));
    ASSERT_TRUE(peaks.has_value()) << k.w << " x " << k.h;
    ASSERT_EQ(peaks->size(), pairs.size());
    std::printf("%s\n", accel->lastNote().c_str());
    for (std::size_t i = 0; i < pairs.size(); ++i) {
      const detect::detail::Link cpu =
          detect::detail::measureLink(images, pairs[i].first, pairs[i].second, 0.0);
      const detect::RegistrationLinkPeak& d = (*peaks)[i];
      ASSERT_TRUE(d.ok);
      const double bin = images.bin();
      std::printf("%d x %d%s pair (%zu, %zu): device (%.6f, %.6f) SNR %.4f, CPU (%.6f, %.6f) SNR %.4f\n", k.w,
                  k.h, k.masked ? " masked" : "", pairs[i].first, pairs[i].second, d.dx * bin, d.dy * bin,
                  d.snr, cpu.step.x, cpu.step.y, cpu.snr);
      EXPECT_NEAR(d.dx * bin, cpu.step.x, 1e-3 * bin) << "pair " << i;
      EXPECT_NEAR(d.dy * bin, cpu.step.y, 1e-3 * bin) << "pair " << i;
      EXPECT_NEAR(d.snr, cpu.snr, 1e-4 * cpu.snr) << "pair " << i;
    }
    // The drift between neighbours, (0.8, -0.45) px a frame, is found unbinned (binned 2x2, the sub-pixel
    // steps of the binned images are biased towards whole binned pixels, on the CPU as here).
    if (images.bin() == 1) {
      EXPECT_NEAR((*peaks)[0].dx, 0.8, 0.1);
      EXPECT_NEAR((*peaks)[0].dy, -0.45, 0.1);
    }
    // Once the pipeline says the frames may have changed, the device declines.
    accel->framesUnchangedSinceFrameBackgrounds(cube, false);
    EXPECT_FALSE(accel->registrationLinks(cube, batchOf(images, pairs)).has_value());
  }
  // A transform length with a prime factor of 7 (518 = 2 x 7 x 37): declined.
  FrameCube odd = starField(518, 256, 4, 6, false);
  NullProgress progress;
  CancelToken cancel;
  accel->removeFrameBackgrounds(odd, {}, progress, cancel);
  accel->framesUnchangedSinceFrameBackgrounds(odd, true);
  const detect::detail::StarImages images(odd);
  EXPECT_FALSE(accel->registrationLinks(odd, batchOf(images, {{1, 0}})).has_value());
}

// Through measureRegistration: a 140-frame sequence takes the sampled path, all 64 links from the device,
// and gives the CPU's model, links and residuals (rms and max within 1e-3 px).
TEST(GpuRegistrationLinks, MeasureRegistrationTakesThemFromTheDevice) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  FrameCube cube = starField(512, 512, 140, 7, true);
  NullProgress progress;
  CancelToken cancel;
  accel->removeFrameBackgrounds(cube, {}, progress, cancel);
  accel->framesUnchangedSinceFrameBackgrounds(cube, true);
  const detect::Registration cpu = detect::measureRegistration(cube, std::nullopt, {}, progress, cancel);
  detect::RegistrationHooks hooks;
  hooks.links = [&](const FrameCube& c, const detect::RegistrationLinkBatch& b) {
    return accel->registrationLinks(c, b);
  };
  const detect::Registration dev =
      detect::measureRegistration(cube, std::nullopt, {}, progress, cancel, hooks);
  std::printf("CPU: %s\ndevice: %s\n", cpu.note.c_str(), dev.note.c_str());
  EXPECT_EQ(dev.linksElsewhere, 64);
  EXPECT_EQ(cpu.linksElsewhere, 0);
  EXPECT_EQ(dev.model, cpu.model);
  EXPECT_EQ(dev.model, detect::Registration::Model::Linear);
  EXPECT_EQ(dev.linksMeasured, cpu.linksMeasured);
  EXPECT_NEAR(dev.rmsPx, cpu.rmsPx, 1e-3);
  EXPECT_NEAR(dev.maxPx, cpu.maxPx, 1e-3);
  EXPECT_NEAR(dev.rate.vx, cpu.rate.vx, 1e-2);
  EXPECT_NEAR(dev.rate.vy, cpu.rate.vy, 1e-2);
}

}  // namespace
}  // namespace st
