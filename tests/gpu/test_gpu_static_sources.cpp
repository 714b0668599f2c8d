// The static sources' matched-filtered SNR maps made on the device (issue 16:
// PreprocessAccelerator::filteredSnr, handed to findStaticSources through SkyStackCache::setSnrProvider):
//  - against the CPU's own map (detail::filteredSnr, white-box), bit for bit: 112 images from 1 x 1 to
//    300 x 37 at four FWHM, around the kernel's and the AVX2 blocks' edges, counts with zeros;
//  - findStaticSources of a drifting field with the device's maps and with the CPU's: the same stars (every
//    field, exactly) and the same masks.
// Skips when no CUDA device is usable.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <optional>
#include <random>
#include <vector>

#include "../../core/detect/star_footprint.hpp"  // white-box: the CPU's filteredSnr
#include "require_gpu_preprocess.hpp"
#include "st/common/units.hpp"
#include "st/detect/sky_stack.hpp"
#include "st/detect/static_sources.hpp"
#include "st/gpu/preprocess.hpp"
#include "st/pipeline/preprocess_accelerator.hpp"

namespace st {
namespace {

// The CPU's map (detail::filteredSnr: scalar edge columns, AVX2 blocks of 16 inside) against the device's,
// made from the same FilteredSnrInputs: widths around the kernel's and the AVX2 blocks' edges, images smaller
// than the kernel, counts with zeros (no SNR there) and a few bright pixels.
TEST(GpuFilteredSnr, EqualsTheCpuBitForBit) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  std::mt19937 rng(5);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::size_t images = 0, pixels = 0, nonzero = 0;
  for (const double fwhm : {1.2, 2.5, 3.57, 5.0}) {
    const int r = std::max(1, static_cast<int>(std::ceil(1.5 * fwhm)));
    for (const int w : {1, r, 2 * r + 1, 2 * r + 16, 2 * r + 17, 2 * r + 40, 300})
      for (const int h : {1, r + 1, 2 * r + 3, 37}) {
        Image resid(w, h), count(w, h);
        for (std::size_t i = 0; i < resid.size(); ++i) {
          count.pixels[i] = u(rng) < 0.1 ? 0.0f : static_cast<float>(1 + static_cast<int>(40 * u(rng)));
          resid.pixels[i] = 3.0f * g(rng) + (i % 97 == 0 ? 50.0f : 0.0f);
        }
        int asked = 0;
        const detect::SkyStackCache::SnrProvider device = [&](const detect::FilteredSnrInputs& in) {
          ++asked;
          return accel->filteredSnr(in);
        };
        const std::vector<float> cpu = detect::detail::filteredSnr(resid, count, 3.1, fwhm);
        const std::vector<float> dev = detect::detail::filteredSnr(resid, count, 3.1, fwhm, &device);
        ASSERT_EQ(asked, 1);
        ASSERT_EQ(dev.size(), cpu.size());
        std::size_t bad = 0, first = 0;
        for (std::size_t i = 0; i < cpu.size(); ++i) {
          nonzero += cpu[i] != 0.0f;
          if (std::memcmp(&dev[i], &cpu[i], sizeof(float)) != 0 && bad++ == 0) first = i;
        }
        EXPECT_EQ(bad, 0u) << w << "x" << h << ", FWHM " << fwhm << ": first at " << first << ": "
                           << dev[first] << " vs " << cpu[first];
        ++images;
        pixels += cpu.size();
      }
  }
  EXPECT_EQ(images, 4u * 7u * 4u);
  EXPECT_GT(nonzero, pixels / 2);
}

/// Stars drifting (0.8, 0.1) px/s over 60 frames 0.5 s apart on sky 100 with noise sigma 3; some faint enough
/// to be found only after the filter.
FrameCube driftingField() {
  constexpr int w = 128, h = 96, n = 60;
  constexpr Velocity drift{0.8, 0.1};
  FrameCube c(w, h, n);
  std::mt19937 rng(17);
  std::normal_distribution<float> g(0.0f, 3.0f);
  struct StarAt {
    double x, y, amp;
  };
  // The last three are below the per-pixel threshold in the stack (amplitude 1.5-2 on noise 3 over 60
  // frames: SNR ~4-5 a pixel) and above it after the filter: the search then looks at the halves' maps too.
  const std::vector<StarAt> stars = {{30.2, 20.7, 600.0}, {80.5, 60.1, 120.0}, {50.3, 75.6, 30.0},
                                     {100.8, 30.2, 8.0},  {20.1, 60.9, 5.0},   {65.6, 40.4, 2500.0},
                                     {110.3, 80.4, 2.0},  {15.6, 85.2, 1.8},   {90.2, 15.7, 1.5}};
  for (int k = 0; k < n; ++k)
    c.info()[k].mjdMid = 60000.0 + 0.5 * k / kSecondsPerDay;
  const std::vector<double> dt = c.timeOffsetsS();
  for (int k = 0; k < n; ++k) {
    float* f = c.frame(k);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        double v = 100.0 + g(rng);
        for (const StarAt& s : stars) {
          const double dx = x - (s.x + drift.vx * dt[k]), dy = y - (s.y + drift.vy * dt[k]);
          v += s.amp * std::exp(-(dx * dx + dy * dy) / (2 * 1.4 * 1.4));
        }
        f[static_cast<std::size_t>(y) * w + x] = static_cast<float>(v);
      }
  }
  return c;
}

TEST(GpuFilteredSnr, StaticSourcesWithTheDeviceMapsEqualTheCpus) {
  const FrameCube cube = driftingField();
  detect::StaticSourceParams params;
  params.psfFwhmPx = 3.3;
  NullProgress p;
  CancelToken c;
  detect::SkyStackCache cpuCache, devCache;
  // The CPU's search counts the maps (its provider declines each): the stack's two analyses and, for the
  // faint stars seen only after the filter, the halves' two maps. The device's makes every one of them.
  int cpuMaps = 0, asked = 0, made = 0;
  cpuCache.setSnrProvider([&](const detect::FilteredSnrInputs&) -> std::optional<std::vector<float>> {
    ++cpuMaps;
    return std::nullopt;
  });
  const detect::StaticSources cpu =
      detect::findStaticSources(cube, {0.8, 0.1}, 100.0, params, p, c, &cpuCache);
  ASSERT_EQ(cpuMaps, 4);
  ST_REQUIRE_GPU_PREPROCESS(accel);
  devCache.setSnrProvider([&](const detect::FilteredSnrInputs& in) {
    ++asked;
    std::optional<std::vector<float>> m = accel->filteredSnr(in);
    made += m ? 1 : 0;
    return m;
  });
  const detect::StaticSources dev =
      detect::findStaticSources(cube, {0.8, 0.1}, 100.0, params, p, c, &devCache);
  EXPECT_EQ(asked, cpuMaps);
  EXPECT_EQ(made, asked);
  ASSERT_GE(cpu.stars.size(), 4u);
  ASSERT_EQ(dev.stars.size(), cpu.stars.size());
  for (std::size_t i = 0; i < cpu.stars.size(); ++i) {
    const detect::Star &a = cpu.stars[i], &b = dev.stars[i];
    EXPECT_EQ(b.x, a.x) << i;
    EXPECT_EQ(b.y, a.y) << i;
    EXPECT_EQ(b.flux, a.flux) << i;
    EXPECT_EQ(b.snr, a.snr) << i;
    EXPECT_EQ(b.filteredSnr, a.filteredSnr) << i;
    EXPECT_EQ(b.pixels, a.pixels) << i;
  }
  EXPECT_EQ(dev.mask.canvas(), cpu.mask.canvas());
  EXPECT_EQ(dev.moverMask.canvas(), cpu.moverMask.canvas());
  EXPECT_EQ(dev.stackNoise, cpu.stackNoise);
}

}  // namespace
}  // namespace st
