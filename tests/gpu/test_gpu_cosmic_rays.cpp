// The cosmic rays (calib::removeCosmicRays) with their protection's three stacks at the sky rate and the
// seeds' pre-test made on the device from the prefetched cube (issue 16): the same protected pixels, hits
// and filled cube as on the CPU, with and without a mask. Skips when no CUDA device is usable.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <optional>
#include <random>

#include "prefetch_wait.hpp"
#include "require_gpu_preprocess.hpp"
#include "st/calib/cosmic_rays.hpp"
#include "st/common/units.hpp"
#include "st/detect/sky_stack.hpp"
#include "st/gpu/preprocess.hpp"
#include "st/pipeline/preprocess_accelerator.hpp"

namespace st {
namespace {

using test::whenUploaded;

/// 64 x 48 x 40 frames of noise (sigma 3 on 100) with a star moving 0.2 px per frame and 30 cosmic rays: few
/// enough (2.4e-4 of the pixels) not to lift the measured excess tail (cosmic_rays.hpp).
FrameCube cosmicRayCube(bool withMask, int w = 64, int h = 48) {
  constexpr int n = 40;
  FrameCube c(w, h, n);
  std::mt19937 rng(23);
  std::normal_distribution<float> g(0.0f, 3.0f);
  for (int k = 0; k < n; ++k) {
    c.info()[k].mjdMid = 60000.0 + 0.5 * k / kSecondsPerDay;
    float* f = c.frame(k);
    for (int i = 0; i < w * h; ++i)
      f[i] = 100.0f + g(rng);
    const double sx = 10.0 + 0.2 * k, sy = 24.3;
    for (int y = 18; y <= 30; ++y)
      for (int x = 0; x < w; ++x) {
        const double r2 = (x - sx) * (x - sx) + (y - sy) * (y - sy);
        f[y * w + x] += static_cast<float>(400.0 * std::exp(-r2 / (2.0 * 1.5 * 1.5)));
      }
  }
  std::uniform_int_distribution<std::size_t> any(0, c.pixels().size() - 1);
  for (int hit = 0; hit < 30; ++hit)
    c.pixels()[any(rng)] += 600.0f;
  if (withMask) {
    c.mask().assign(c.pixels().size(), 0);
    for (std::size_t i = 0; i < c.mask().size(); i += 97)
      c.mask()[i] = 1;
  }
  return c;
}

TEST(GpuSkyStack, CosmicRayProtectionFromTheDeviceEqualsTheCpu) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  for (const bool withMask : {false, true}) {
    SCOPED_TRACE(withMask ? "with a mask" : "without a mask");
    FrameCube c = cosmicRayCube(withMask);
    FrameCube cpu = c;
    const std::shared_ptr<void> guard = accel->prefetch(c);
    calib::CosmicRayParams params;
    params.skyRate = {0.4, 0.0};  // px/s: the star's 0.2 px per frame
    params.fill = calib::CosmicRayParams::Fill::TimeNeighbours;
    int asked = 0, made = 0;
    const detect::SkyStackCache::Provider device = [&](const FrameCube& cube, Velocity rate, double subtract,
                                                       std::size_t first, std::size_t last) {
      ++asked;
      std::optional<detect::SkyStack> s =
          whenUploaded([&] { return accel->skyStack(cube, rate, subtract, first, last); });
      made += s ? 1 : 0;
      return s;
    };
    NullProgress progress;
    CancelToken cancel;
    const calib::CosmicRayResult d = calib::removeCosmicRays(c, params, progress, cancel, &device);
    const calib::CosmicRayResult h = calib::removeCosmicRays(cpu, params, progress, cancel);
    EXPECT_EQ(asked, params.protectBlocks);
    EXPECT_EQ(made, params.protectBlocks);
    EXPECT_GE(h.total, 20u);
    EXPECT_GT(h.protectedPixels, 0u);
    EXPECT_EQ(d.protectedPixels, h.protectedPixels);
    EXPECT_EQ(d.pixels, h.pixels);
    EXPECT_EQ(d.total, h.total);
    EXPECT_EQ(std::memcmp(c.pixels().data(), cpu.pixels().data(), c.pixels().size() * sizeof(float)), 0);
  }
}

TEST(GpuCosmicRays, PreTestFromTheDeviceEqualsTheCpu) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  for (const bool withMask : {false, true}) {
    SCOPED_TRACE(withMask ? "with a mask" : "without a mask");
    // 61 x 47 pixels: frames that start inside a word; a NaN sample (it passes, and makes its time
    // neighbours' maximum NaN).
    FrameCube c = cosmicRayCube(withMask, 61, 47);
    c.pixels()[5 * c.framePixels() + 77] = std::nanf("");
    FrameCube cpu = c;
    const std::shared_ptr<void> guard = accel->prefetch(c);
    for (const float thr : {9.0f, 15.0f, 25.0f}) {
      SCOPED_TRACE(thr);
      const std::optional<calib::CosmicRayPreTestWords> d =
          whenUploaded([&] { return accel->cosmicRayPreTest(c, thr); });
      ASSERT_TRUE(d.has_value());
      const calib::CosmicRayPreTestWords h = calib::cosmicRayPreTestWords(cpu, thr);
      EXPECT_GT(h.index.size(), 10u);
      EXPECT_EQ(d->index, h.index);
      EXPECT_EQ(d->bits, h.bits);
    }
    // Uploaded now: where too many words pass (over one in 16, here at threshold 0) the device declines and
    // the CPU makes them.
    EXPECT_FALSE(accel->cosmicRayPreTest(c, 0.0f).has_value());
    calib::CosmicRayParams params;
    params.skyRate = {0.4, 0.0};
    params.fill = calib::CosmicRayParams::Fill::TimeNeighbours;
    const calib::CosmicRayPreTest device = [&](const FrameCube& cube, float thr) {
      return whenUploaded([&] { return accel->cosmicRayPreTest(cube, thr); });
    };
    NullProgress progress;
    CancelToken cancel;
    const calib::CosmicRayResult dr = calib::removeCosmicRays(c, params, progress, cancel, nullptr, &device);
    const calib::CosmicRayResult hr = calib::removeCosmicRays(cpu, params, progress, cancel);
    EXPECT_TRUE(dr.preTestProvided);
    EXPECT_FALSE(hr.preTestProvided);
    EXPECT_GE(hr.total, 20u);
    EXPECT_EQ(dr.pixels, hr.pixels);
    EXPECT_EQ(dr.sourceSeeds, hr.sourceSeeds);
    EXPECT_EQ(std::memcmp(c.pixels().data(), cpu.pixels().data(), c.pixels().size() * sizeof(float)), 0);
  }
}

}  // namespace
}  // namespace st
