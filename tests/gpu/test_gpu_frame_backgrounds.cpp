// The frame backgrounds (stats::removeFrameBackgrounds: SEP's sep_background per frame, its spline
// subtracted, the median level restored) on the device (issue 16) against the CPU, which calls libsep:
// frames whose size is not a multiple of the mesh (SEP's short last column and row of meshes), a sky
// gradient, stars, cosmic rays, NaN samples, with and without a mask, a masked region that leaves meshes
// "bad" (SEP fills them from their nearest valid meshes), a frame of one mesh row, the 512^2 frames of the
// paper's problem. The frames stay on the device: once the pipeline vouches for them
// (framesUnchangedSinceFrameBackgrounds), the global background (within 1e-12) and the hot pixels' block
// means (the same pixels) come from them without an upload, and not after it says they changed. Levels and
// rms are SEP's within float rounding (the device reduces SEP's double sums in another order: rounding only),
// every pixel within 1e-6 relative of the CPU's. A device failure leaves the cube as it was and the CPU does
// the work (removeFrameBackgroundsOn). Every test skips without a device.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <optional>
#include <random>
#include <thread>
#include <vector>

#include "require_gpu_preprocess.hpp"
#include "st/calib/calibration.hpp"
#include "st/common/error.hpp"
#include "st/common/progress.hpp"
#include "st/detect/hot_pixels.hpp"
#include "st/detect/sky_stack.hpp"
#include "st/gpu/preprocess.hpp"
#include "st/pipeline/preprocess_accelerator.hpp"
#include "st/stats/background.hpp"
#include "st/stats/noise_model.hpp"

namespace st {
namespace {

/// A calibrated-looking cube: sky ~1000 with a gradient that changes from frame to frame, noise, a few
/// stars, cosmic rays and NaN samples; with `withMask`, scattered masked samples and a masked block large
/// enough to make some meshes bad.
FrameCube skyCube(int w, int h, int n, unsigned seed, bool withMask) {
  FrameCube c(w, h, static_cast<std::size_t>(n));
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  if (withMask) c.mask().assign(c.pixels().size(), 0);
  for (int k = 0; k < n; ++k) {
    float* f = c.frame(k);
    const double level = 1000.0 + 20.0 * u(rng), gx = 0.2 * u(rng), gy = 0.1 * (u(rng) - 0.5);
    const double sx = w * u(rng), sy = h * u(rng);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * w + x;
        const double r2 = (x - sx) * (x - sx) + (y - sy) * (y - sy);
        double v = level + gx * x + gy * y + 0.002 * (x - w / 2.0) * (y - h / 2.0) / 10.0 + 12.0 * g(rng);
        v += 5000.0 * std::exp(-r2 / 8.0);  // a star
        if (u(rng) < 0.001) v += 3000.0;    // a cosmic ray
        f[i] = static_cast<float>(v);
        if (u(rng) < 0.0005) f[i] = std::numeric_limits<float>::quiet_NaN();
        if (withMask) {
          std::uint8_t& m = c.mask()[static_cast<std::size_t>(k) * w * h + i];
          m = u(rng) < 0.01 ? 1 : 0;
          if (x < 40 && y < 40 && k % 3 == 1) m = 1;  // whole meshes masked in some frames
        }
      }
  }
  return c;
}

void expectSame(const FrameCube& in, const stats::FrameBackgroundParams& params,
                pipeline::PreprocessAccelerator& accel) {
  NullProgress progress;
  CancelToken cancel;
  FrameCube cpu = in, dev = in;
  const stats::FrameBackgrounds a = stats::removeFrameBackgrounds(cpu, params, progress, cancel);
  const stats::FrameBackgrounds b = accel.removeFrameBackgrounds(dev, params, progress, cancel);
  std::printf("%s\n", accel.lastNote().c_str());
  ASSERT_EQ(a.level.size(), b.level.size());
  for (std::size_t n = 0; n < a.level.size(); ++n) {
    EXPECT_NEAR(b.level[n], a.level[n], 1e-6 * std::fabs(a.level[n])) << "frame " << n;
    EXPECT_NEAR(b.rms[n], a.rms[n], 1e-5 * std::fabs(a.rms[n])) << "frame " << n;
  }
  EXPECT_NEAR(b.restoredLevel, a.restoredLevel, 1e-6 * std::fabs(a.restoredLevel));
  EXPECT_EQ(b.framesSkipped, a.framesSkipped);
  std::size_t bad = 0, equal = 0, nans = 0;
  double worst = 0.0;
  for (std::size_t i = 0; i < cpu.pixels().size(); ++i) {
    const float c = cpu.pixels()[i], d = dev.pixels()[i];
    if (std::isnan(c) || std::isnan(d)) {
      bad += std::isnan(c) != std::isnan(d);
      ++nans;
      continue;
    }
    const double diff = std::fabs(double(d) - double(c));
    worst = std::max(worst, diff);
    equal += c == d;
    bad += !(diff <= 1e-6 * std::max(1.0, std::fabs(double(c))));
  }
  std::printf("pixels equal %zu of %zu, largest difference %.3g, NaN %zu\n", equal, cpu.pixels().size(),
              worst, nans);
  EXPECT_EQ(bad, 0u);
  EXPECT_GT(nans, 0u);
}

TEST(GpuFrameBackgrounds, MatchesSepOnOddSizes) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  const FrameCube in = skyCube(200, 150, 12, 1, false);
  expectSame(in, stats::FrameBackgroundParams{true, 64, 3}, *accel);
  expectSame(in, stats::FrameBackgroundParams{true, 32, 3}, *accel);
  expectSame(in, stats::FrameBackgroundParams{true, 24, 5}, *accel);
}

TEST(GpuFrameBackgrounds, MatchesSepWithAMaskAndBadMeshes) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  const FrameCube in = skyCube(160, 130, 9, 2, true);
  expectSame(in, stats::FrameBackgroundParams{true, 32, 3}, *accel);
  expectSame(in, stats::FrameBackgroundParams{true, 16, 1}, *accel);
}

TEST(GpuFrameBackgrounds, MatchesSepOnOneMeshRowAndColumn) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  expectSame(skyCube(300, 40, 5, 3, false), stats::FrameBackgroundParams{true, 64, 3}, *accel);
  expectSame(skyCube(40, 300, 5, 4, true), stats::FrameBackgroundParams{true, 64, 3}, *accel);
}

TEST(GpuFrameBackgrounds, MatchesSepOnPaperFrames) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  expectSame(skyCube(512, 512, 6, 5, false), stats::FrameBackgroundParams{}, *accel);
}

TEST(GpuFrameBackgrounds, TheOnFunctionUsesTheDeviceAndNotesIt) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  const FrameCube in = skyCube(128, 96, 4, 6, false);
  NullProgress progress;
  CancelToken cancel;
  FrameCube cpu = in, dev = in;
  std::vector<std::string> notes;
  const auto a = stats::removeFrameBackgrounds(cpu, {}, progress, cancel);
  const auto b = pipeline::removeFrameBackgroundsOn(accel.get(), dev, {}, progress, cancel, notes);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("frame backgrounds on cuda"), std::string::npos) << notes[0];
  EXPECT_NEAR(b.restoredLevel, a.restoredLevel, 1e-6 * a.restoredLevel);
  // Disabled: nothing changes, as on the CPU.
  FrameCube off = in;
  const auto c =
      accel->removeFrameBackgrounds(off, stats::FrameBackgroundParams{false, 64, 3}, progress, cancel);
  EXPECT_EQ(std::memcmp(off.pixels().data(), in.pixels().data(), in.pixels().size() * sizeof(float)), 0);
  EXPECT_EQ(c.level.size(), in.frameCount());
}

// 30 frames of 150 x 120 with two hot pixels: raised in every frame, their neighbours not.
FrameCube hotPixelCube(unsigned seed, bool withMask) {
  FrameCube cube = skyCube(150, 120, 30, seed, withMask);
  for (std::size_t k = 0; k < cube.frameCount(); ++k)
    for (const std::size_t i : {std::size_t{40 * 150 + 70}, std::size_t{90 * 150 + 20}})
      cube.frame(k)[i] += 400.0f;
  return cube;
}

TEST(GpuFrameBackgrounds, KeptFramesGiveTheGlobalBackgroundAndHotPixels) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  for (const bool withMask : {false, true}) {
    FrameCube cube = hotPixelCube(7, withMask);
    NullProgress progress;
    CancelToken cancel;
    accel->removeFrameBackgrounds(cube, {}, progress, cancel);
    accel->framesUnchangedSinceFrameBackgrounds(cube, true);
    const stats::ClipStats g = accel->globalBackground(cube, {});
    EXPECT_NE(accel->lastNote().find("no upload"), std::string::npos) << accel->lastNote();
    const stats::ClipStats c = stats::globalBackground(cube, {});
    EXPECT_NEAR(g.mean, c.mean, 1e-12 * std::fabs(c.mean));
    EXPECT_NEAR(g.sigma, c.sigma, 1e-12 * c.sigma);
    EXPECT_EQ(g.count, c.count);
    const detect::HotPixelParams hp;
    const auto excess = accel->hotPixelExcess(cube, c.mean, hp);
    ASSERT_TRUE(excess.has_value());
    const auto dev =
        detect::hotPixelsFromExcess(*excess, cube.width(), cube.height(), cube.frameCount(), c.sigma, hp);
    const auto cpu = detect::findHotPixels(cube, c.mean, c.sigma, hp, cancel);
    EXPECT_EQ(dev, cpu);
    EXPECT_GE(cpu.size(), 2u);
    // Once the pipeline says the pixels may have changed, nothing comes from the kept frames.
    accel->framesUnchangedSinceFrameBackgrounds(cube, false);
    EXPECT_FALSE(accel->hotPixelExcess(cube, c.mean, hp).has_value());
    accel->globalBackground(cube, {});
    EXPECT_EQ(accel->lastNote().find("no upload"), std::string::npos) << accel->lastNote();
  }
}

// The hot pixels masked on the host are set in the device's kept mask too (maskedInAllFrames, issue 16): the
// prefetch then takes the frames and the mask from the device with no upload, and its stacks at the sky rate
// (whose counts and maxima see every masked sample) equal the CPU's bit for bit, with and without a mask
// before the hot pixels. Without the pipeline's word after hotPixelExcess, the mask is uploaded as before.
TEST(GpuFrameBackgrounds, HotPixelsMaskedOnTheDeviceGiveThePrefetchTheHostsMask) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  for (const bool told : {true, false})
    for (const bool withMask : {false, true}) {
      SCOPED_TRACE(std::string(withMask ? "a mask before" : "no mask before") +
                   (told ? ", told" : ", not told"));
      FrameCube cube = hotPixelCube(9, withMask);
      NullProgress progress;
      CancelToken cancel;
      accel->removeFrameBackgrounds(cube, {}, progress, cancel);
      accel->framesUnchangedSinceFrameBackgrounds(cube, true);
      const stats::ClipStats g = accel->globalBackground(cube, {});
      const detect::HotPixelParams hp;
      const auto excess = accel->hotPixelExcess(cube, g.mean, hp);
      ASSERT_TRUE(excess.has_value());
      const auto hot =
          detect::hotPixelsFromExcess(*excess, cube.width(), cube.height(), cube.frameCount(), g.sigma, hp);
      ASSERT_GE(hot.size(), 2u);
      detect::maskPixelsInAllFrames(cube, hot);
      if (told) accel->maskedInAllFrames(cube, hot);
      const std::shared_ptr<void> guard = accel->prefetch(cube);
      const std::string note = accel->lastNote();
      EXPECT_EQ(note.find("hot pixels set on the device") != std::string::npos, told) << note;
      EXPECT_NE(note.find("the frame backgrounds' frames"), std::string::npos) << note;
      const Velocity rate{0.9, -0.3};
      for (const auto& [first, last] : {std::pair<std::size_t, std::size_t>{0, 30}, {10, 20}}) {
        std::optional<detect::SkyStack> dev;
        for (int tries = 0; tries < 1000 && !dev; ++tries) {
          dev = accel->skyStack(cube, rate, g.mean, first, last);
          if (!dev) std::this_thread::sleep_for(std::chrono::milliseconds(10));
        }
        ASSERT_TRUE(dev.has_value());
        accel->finishHostCopies();
        const detect::SkyStack cpu =
            detect::stackAtSkyRate(cube, rate, g.mean, progress, cancel, first, last);
        ASSERT_EQ(dev->count.pixels.size(), cpu.count.pixels.size());
        EXPECT_EQ(std::memcmp(dev->count.data(), cpu.count.data(), cpu.count.pixels.size() * sizeof(float)),
                  0);
        EXPECT_EQ(std::memcmp(dev->max.data(), cpu.max.data(), cpu.max.pixels.size() * sizeof(float)), 0);
        EXPECT_EQ(std::memcmp(dev->mean.data(), cpu.mean.data(), cpu.mean.pixels.size() * sizeof(float)), 0);
      }
    }
}

// The frames' download behind the stages after the frame backgrounds (allowFrameDownloadBehind, issue 16):
// frames asked for with waitForHostFrames (from several threads, the last ones first) are the synchronous
// download's bit for bit before the rest has landed; the global background and hot pixels come from the kept
// frames meanwhile, equal to the synchronous run's; finishHostCopies leaves the whole cube equal. Without
// the pipeline's word the download is done on return, as before.
TEST(GpuFrameBackgrounds, DownloadBehindGivesTheSameFramesWhenWaitedFor) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  for (const bool withMask : {false, true}) {
    // 1 MB frames: 32 to a download piece, so asking for one frame moves one piece ahead of up to 7 others.
    const FrameCube in = skyCube(512, 512, 240, 8, withMask);
    NullProgress progress;
    CancelToken cancel;
    FrameCube sync = in;
    accel->removeFrameBackgrounds(sync, {}, progress, cancel);
    EXPECT_EQ(accel->lastNote().find("behind"), std::string::npos) << accel->lastNote();
    accel->framesUnchangedSinceFrameBackgrounds(sync, true);
    const stats::ClipStats gSync = accel->globalBackground(sync, {});
    const auto hotSync = accel->hotPixelExcess(sync, gSync.mean, {});
    ASSERT_TRUE(hotSync.has_value());

    FrameCube behind = in;
    accel->allowFrameDownloadBehind(true);
    accel->removeFrameBackgrounds(behind, {}, progress, cancel);
    accel->allowFrameDownloadBehind(false);
    EXPECT_NE(accel->lastNote().find("download behind"), std::string::npos) << accel->lastNote();
    accel->framesUnchangedSinceFrameBackgrounds(behind, true);
    const std::size_t np = in.framePixels();
    const std::vector<std::size_t> asked{239, 3, 120, 200, 17, 238};
    std::vector<int> same(asked.size(), 0);
    {
      std::vector<std::jthread> threads;
      for (std::size_t k = 0; k < asked.size(); ++k)
        threads.emplace_back([&, k] {
          accel->waitForHostFrames(behind, asked[k], asked[k] + 1);
          same[k] = std::memcmp(behind.frame(asked[k]), sync.frame(asked[k]), np * sizeof(float)) == 0;
        });
    }
    for (std::size_t k = 0; k < asked.size(); ++k)
      EXPECT_TRUE(same[k]) << "frame " << asked[k] << (withMask ? " (masked cube)" : "");
    // The kept frames serve while the rest of the download may still run.
    const stats::ClipStats g = accel->globalBackground(behind, {});
    EXPECT_NE(accel->lastNote().find("no upload"), std::string::npos) << accel->lastNote();
    EXPECT_EQ(g.mean, gSync.mean);
    EXPECT_EQ(g.sigma, gSync.sigma);
    EXPECT_EQ(g.count, gSync.count);
    const auto hot = accel->hotPixelExcess(behind, g.mean, {});
    ASSERT_TRUE(hot.has_value());
    EXPECT_EQ(*hot, *hotSync);
    accel->finishHostCopies();
    EXPECT_EQ(std::memcmp(behind.pixels().data(), sync.pixels().data(), in.pixels().size() * sizeof(float)),
              0);
  }
}

// The raw frames calibrated on the device after the frame backgrounds' upload
// (calibrateAndRemoveFrameBackgrounds): the same cube and levels, bit for bit, as the CPU's pixel
// calibration followed by the device's frame backgrounds, with an overscan, bias, dark and flat; with the
// bias alone; and not done (none, the cube untouched) when a master does not fit the frames.
TEST(GpuFrameBackgrounds, CalibratedOnTheDeviceEqualsTheCpusCalibration) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  const int w = 150, h = 110, n = 12;
  FrameCube raw = skyCube(w, h, n, 31, true);
  for (int k = 0; k < n; ++k)
    raw.info()[k].exposureS = 0.5 + 0.01 * k;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  Image bias(w, h), dark(w, h), flat(w, h);
  for (std::size_t i = 0; i < bias.pixels.size(); ++i) {
    bias.pixels[i] = 300.0f + 7.0f * u(rng);
    dark.pixels[i] = 0.3f * u(rng);
    flat.pixels[i] = 0.9f + 0.2f * u(rng);
  }
  for (const bool all : {true, false}) {
    SCOPED_TRACE(all ? "overscan, bias, dark, flat" : "bias only");
    calib::CalibrationPlan plan;
    plan.overscan.assign(n, 0.0f);
    plan.darkSeconds.resize(n);
    for (int k = 0; k < n; ++k) {
      plan.darkSeconds[k] = static_cast<float>(raw.info()[k].exposureS);
      if (all) plan.overscan[k] = 10.0f + 0.37f * k;
    }
    plan.bias = &bias;
    if (all) {
      plan.darkPerS = &dark;
      plan.flat = &flat;
    }
    NullProgress progress;
    CancelToken cancel;
    FrameCube cpu = raw, dev = raw;
    calib::applyPixelCalibration(cpu, plan, progress, cancel);
    const stats::FrameBackgrounds a = accel->removeFrameBackgrounds(cpu, {}, progress, cancel);
    const std::optional<stats::FrameBackgrounds> b =
        accel->calibrateAndRemoveFrameBackgrounds(dev, plan, {}, progress, cancel);
    ASSERT_TRUE(b.has_value());
    EXPECT_NE(accel->lastNote().find("calibration and frame backgrounds"), std::string::npos)
        << accel->lastNote();
    EXPECT_EQ(std::memcmp(cpu.pixels().data(), dev.pixels().data(), cpu.pixels().size() * sizeof(float)), 0);
    EXPECT_EQ(a.level, b->level);
    EXPECT_EQ(a.rms, b->rms);
  }
  Image small(w - 1, h);
  calib::CalibrationPlan wrong;
  wrong.overscan.assign(n, 0.0f);
  wrong.darkSeconds.assign(n, 1.0f);
  wrong.bias = &small;
  FrameCube untouched = raw;
  NullProgress progress;
  CancelToken cancel;
  EXPECT_FALSE(accel->calibrateAndRemoveFrameBackgrounds(untouched, wrong, {}, progress, cancel).has_value());
  EXPECT_EQ(std::memcmp(untouched.pixels().data(), raw.pixels().data(), raw.pixels().size() * sizeof(float)),
            0);
}

}  // namespace
}  // namespace st
