// The static sources' matched-filtered SNR maps made on the device (issue 16:
// PreprocessAccelerator::filteredSnr, handed to findStaticSources through SkyStackCache::setSnrProvider):
//  - against the formula of detect::FilteredSnrInputs computed here in plain loops, bit for bit: images wider
//    than the AVX2 blocks of the CPU path, one smaller than the kernel, counts with zeros (no SNR there);
//  - findStaticSources of a drifting field with the device's maps and with the CPU's: the same stars (every
//    field, exactly) and the same masks.
// Skips when no CUDA device is usable.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <optional>
#include <random>
#include <vector>

#include "require_gpu_preprocess.hpp"
#include "st/common/units.hpp"
#include "st/detect/sky_stack.hpp"
#include "st/detect/static_sources.hpp"
#include "st/gpu/preprocess.hpp"
#include "st/pipeline/preprocess_accelerator.hpp"

namespace st {
namespace {

std::vector<float> referenceSnr(const detect::FilteredSnrInputs& in) {
  const int w = in.width, h = in.height, r = in.r, kw = 2 * r + 1;
  std::vector<float> out(static_cast<std::size_t>(w) * h, 0.0f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double num = 0.0, den = 0.0;
      for (int j = std::max(-r, -y); j <= std::min(r, h - 1 - y); ++j)
        for (int i = std::max(-r, -x); i <= std::min(r, w - 1 - x); ++i) {
          const double k = in.k[static_cast<std::size_t>(j + r) * kw + (i + r)];
          const std::size_t q = static_cast<std::size_t>(y + j) * w + (x + i);
          const double a = k * static_cast<double>(in.rc[q]);
          num += a;
          const double k2 = k * k;
          const double b = k2 * static_cast<double>(in.count[q]);
          den += b;
        }
      if (den > 0)
        out[static_cast<std::size_t>(y) * w + x] = static_cast<float>(num / (in.sigma * std::sqrt(den)));
    }
  return out;
}

TEST(GpuFilteredSnr, EqualsTheFormulaBitForBit) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  std::mt19937 rng(5);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  struct Shape {
    int w, h, r;
  };
  for (const Shape sh : {Shape{300, 20, 6}, Shape{40, 30, 3}, Shape{7, 5, 4}}) {
    const std::size_t np = static_cast<std::size_t>(sh.w) * sh.h;
    std::vector<float> rc(np), count(np);
    for (std::size_t i = 0; i < np; ++i) {
      count[i] = u(rng) < 0.1 ? 0.0f : static_cast<float>(1 + static_cast<int>(40 * u(rng)));
      rc[i] = count[i] * (3.0f * g(rng) + (i % 97 == 0 ? 50.0f : 0.0f));
    }
    const int kw = 2 * sh.r + 1;
    std::vector<double> k(static_cast<std::size_t>(kw) * kw);
    for (int j = -sh.r; j <= sh.r; ++j)
      for (int i = -sh.r; i <= sh.r; ++i)
        k[static_cast<std::size_t>(j + sh.r) * kw + (i + sh.r)] =
            1.0 / std::pow(1.0 + (i * i + j * j) / 4.7, 4.0);
    const detect::FilteredSnrInputs in{rc.data(), count.data(), sh.w, sh.h, k.data(), sh.r, 3.1};
    const std::optional<std::vector<float>> dev = accel->filteredSnr(in);
    ASSERT_TRUE(dev.has_value());
    const std::vector<float> ref = referenceSnr(in);
    ASSERT_EQ(dev->size(), ref.size());
    std::size_t bad = 0, first = 0, nonzero = 0;
    for (std::size_t i = 0; i < np; ++i) {
      nonzero += ref[i] != 0.0f;
      if (std::memcmp(&(*dev)[i], &ref[i], sizeof(float)) != 0 && bad++ == 0) first = i;
    }
    EXPECT_GT(nonzero, np / 2) << sh.w << "x" << sh.h;
    EXPECT_EQ(bad, 0u) << sh.w << "x" << sh.h << " r " << sh.r << ": first at " << first << ": "
                       << (*dev)[first] << " vs " << ref[first];
  }
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
  const std::vector<StarAt> stars = {{30.2, 20.7, 600.0}, {80.5, 60.1, 120.0}, {50.3, 75.6, 30.0},
                                     {100.8, 30.2, 8.0},  {20.1, 60.9, 5.0},   {65.6, 40.4, 2500.0}};
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
  ST_REQUIRE_GPU_PREPROCESS(accel);
  const FrameCube cube = driftingField();
  detect::StaticSourceParams params;
  params.psfFwhmPx = 3.3;
  NullProgress p;
  CancelToken c;
  detect::SkyStackCache cpuCache, devCache;
  int asked = 0, made = 0;
  devCache.setSnrProvider([&](const detect::FilteredSnrInputs& in) {
    ++asked;
    std::optional<std::vector<float>> m = accel->filteredSnr(in);
    made += m ? 1 : 0;
    return m;
  });
  const detect::StaticSources cpu =
      detect::findStaticSources(cube, {0.8, 0.1}, 100.0, params, p, c, &cpuCache);
  const detect::StaticSources dev =
      detect::findStaticSources(cube, {0.8, 0.1}, 100.0, params, p, c, &devCache);
  EXPECT_GE(asked,
            2);  // the stack's two analyses, and the halves' two maps when a source is seen only filtered
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
