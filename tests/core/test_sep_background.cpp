// SEP's per-frame background as synthtrack computes it (st/stats/sep_background.hpp) against libsep itself,
// the oracle: every frame's global level and rms, and every pixel of the subtracted frame, bit for bit.
// Frames chosen to reach every branch: meshes that do not divide the frame, a frame narrower than a mesh,
// one row or one column of meshes, masked and NaN pixels, meshes masked past half (SEP's "bad" meshes,
// filled from their neighbours), integer-valued (quantised) and skewed data with many tied histogram bins,
// bright stars, mesh sizes 16-64 and median filters of 1-5 cells.
#include <cstddef>  // sep.h needs size_t

extern "C" {
#include <sep.h>  // a C header without extern "C" guards
}

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/stats/noise_model.hpp"
#include "st/stats/sep_background.hpp"

namespace st::stats {
namespace {

struct Frame {
  int w = 0, h = 0;
  std::vector<float> pix;
  std::vector<std::uint8_t> mask;  // empty: none
};

enum class Noise { Gaussian, Quantised, Skewed };

Frame makeFrame(int w, int h, std::uint32_t seed, Noise noise, bool masked, bool nans) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::exponential_distribution<double> ex(1.0 / 15.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Frame f;
  f.w = w;
  f.h = h;
  f.pix.resize(static_cast<std::size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double v = 1000.0 + 0.3 * x - 0.2 * y + 40.0 * std::sin(x / 70.0) * std::cos(y / 55.0);
      if (noise == Noise::Gaussian) v += 12.0 * g(rng);
      if (noise == Noise::Quantised) v = std::round(v + 3.0 * g(rng));
      if (noise == Noise::Skewed) v += ex(rng) + 4.0 * g(rng);
      f.pix[static_cast<std::size_t>(y) * w + x] = static_cast<float>(v);
    }
  // Stars: some bright enough to dominate a mesh's histogram tail.
  for (int s = 0; s < (w * h) / 4000 + 2; ++s) {
    const double cx = u(rng) * w, cy = u(rng) * h, peak = 50.0 * std::pow(10.0, 3.0 * u(rng));
    for (int y = std::max(0, int(cy) - 8); y < std::min(h, int(cy) + 9); ++y)
      for (int x = std::max(0, int(cx) - 8); x < std::min(w, int(cx) + 9); ++x) {
        const double r2 = (x - cx) * (x - cx) + (y - cy) * (y - cy);
        f.pix[static_cast<std::size_t>(y) * w + x] += static_cast<float>(peak * std::exp(-r2 / 4.5));
      }
  }
  if (masked) {
    f.mask.assign(f.pix.size(), 0);
    // A block masked past half of a mesh's pixels, scattered masked pixels, a masked column.
    for (int y = 0; y < std::min(h, 50); ++y)
      for (int x = 0; x < std::min(w, 45); ++x)
        f.mask[static_cast<std::size_t>(y) * w + x] = 1;
    for (std::size_t i = 0; i < f.mask.size(); i += 37)
      f.mask[i] = 255;
    for (int y = 0; y < h; ++y)
      f.mask[static_cast<std::size_t>(y) * w + w / 2] = 1;
  }
  if (nans)
    for (std::size_t i = 11; i < f.pix.size(); i += 101)
      f.pix[i] = std::nanf("");
  return f;
}

struct Result {
  float global = 0.0f, rms = 0.0f;
  std::vector<float> pix;  // the frame minus the background, plus `restored`
};

Result withLibsep(const Frame& f, int mesh, int filter, float restored) {
  Result r;
  r.pix = f.pix;
  sep_image im{};
  im.data = r.pix.data();
  im.dtype = SEP_TFLOAT;
  if (!f.mask.empty()) {
    im.mask = f.mask.data();
    im.mdtype = SEP_TBYTE;
    im.maskthresh = 0.0;
  }
  im.w = f.w;
  im.h = f.h;
  im.noise_type = SEP_NOISE_NONE;
  sep_bkg* bkg = nullptr;
  EXPECT_EQ(sep_background(&im, std::min(mesh, f.w), std::min(mesh, f.h), filter, filter, 0.0, &bkg), 0);
  if (!bkg) return r;
  r.global = sep_bkg_global(bkg);
  r.rms = sep_bkg_globalrms(bkg);
  EXPECT_EQ(sep_bkg_subarray(bkg, r.pix.data(), SEP_TFLOAT), 0);
  sep_bkg_free(bkg);
  for (float& v : r.pix)
    v += restored;
  return r;
}

Result withOurs(const Frame& f, int mesh, int filter, float restored) {
  Result r;
  r.pix = f.pix;
  const sep::MeshGrid g = sep::meshGrid(f.w, f.h, mesh);
  const sep::FrameModel m = sep::model(r.pix.data(), f.mask.empty() ? nullptr : f.mask.data(), g, filter);
  r.global = m.global;
  r.rms = m.globalrms;
  sep::subtract(r.pix.data(), g, m, sep::rowTable(g.height, g.bh, g.ny),
                sep::columnTable(g.width, g.bw, g.nx), restored);
  return r;
}

bool sameFloat(float a, float b) {
  return (std::isnan(a) && std::isnan(b)) || std::memcmp(&a, &b, sizeof a) == 0;
}

void expectIdentical(const Frame& f, int mesh, int filter, const std::string& what) {
  SCOPED_TRACE(what);
  const float restored = 987.25f;
  const Result a = withLibsep(f, mesh, filter, restored);
  const Result b = withOurs(f, mesh, filter, restored);
  EXPECT_TRUE(sameFloat(a.global, b.global)) << a.global << " vs " << b.global;
  EXPECT_TRUE(sameFloat(a.rms, b.rms)) << a.rms << " vs " << b.rms;
  ASSERT_EQ(a.pix.size(), b.pix.size());
  std::size_t differ = 0, first = 0;
  for (std::size_t i = 0; i < a.pix.size(); ++i)
    if (!sameFloat(a.pix[i], b.pix[i]) && differ++ == 0) first = i;
  EXPECT_EQ(differ, 0u) << "first at (" << first % f.w << ", " << first / f.w << "): " << a.pix[first]
                        << " vs " << b.pix[first];
}

TEST(SepBackground, EqualsLibsepPixelForPixel) {
  std::uint32_t seed = 1;
  for (Noise noise : {Noise::Gaussian, Noise::Quantised, Noise::Skewed})
    for (bool masked : {false, true})
      for (bool nans : {false, true}) {
        const std::string tag =
            "noise " + std::to_string(int(noise)) + (masked ? " masked" : "") + (nans ? " nans" : "");
        expectIdentical(makeFrame(512, 512, seed++, noise, masked, nans), 64, 3, "512^2 " + tag);
        expectIdentical(makeFrame(300, 217, seed++, noise, masked, nans), 64, 3, "300x217 " + tag);
      }
}

TEST(SepBackground, EqualsLibsepOnOddGridsAndFilters) {
  std::uint32_t seed = 100;
  struct Case {
    int w, h, mesh, filter;
  };
  for (const Case c : {Case{40, 30, 64, 3}, Case{512, 50, 64, 3}, Case{50, 400, 64, 3}, Case{256, 256, 16, 1},
                       Case{256, 200, 32, 5}, Case{129, 511, 64, 1}, Case{1000, 7, 8, 3}})
    for (bool masked : {false, true})
      expectIdentical(makeFrame(c.w, c.h, seed++, Noise::Quantised, masked, false), c.mesh, c.filter,
                      std::to_string(c.w) + "x" + std::to_string(c.h) + " mesh " + std::to_string(c.mesh) +
                          " filter " + std::to_string(c.filter) + (masked ? " masked" : ""));
}

// The cube-level stage: each frame's level and rms, the restored median and every pixel equal to libsep
// applied frame by frame (what removeFrameBackgrounds did before it computed SEP itself).
TEST(SepBackground, RemoveFrameBackgroundsEqualsLibsepFrameByFrame) {
  const int w = 200, h = 150, nf = 9;
  FrameCube cube(w, h, nf);
  cube.mask().assign(cube.pixels().size(), 0);
  std::vector<Frame> frames;
  for (int n = 0; n < nf; ++n) {
    Frame f = makeFrame(w, h, 500 + n, n % 2 ? Noise::Skewed : Noise::Gaussian, true, n == 4);
    for (float& v : f.pix)
      v += 30.0f * n;  // a sky level that changes from frame to frame
    std::memcpy(cube.frame(n), f.pix.data(), f.pix.size() * sizeof(float));
    std::memcpy(cube.mask().data() + std::size_t(n) * w * h, f.mask.data(), f.mask.size());
    frames.push_back(std::move(f));
  }
  std::vector<float> levels;
  for (const Frame& f : frames)
    levels.push_back(withLibsep(f, 64, 3, 0.0f).global);
  std::vector<float> sorted = levels;
  std::nth_element(sorted.begin(), sorted.begin() + nf / 2, sorted.end());
  const float restored = sorted[nf / 2];
  NullProgress progress;
  CancelToken cancel;
  const FrameBackgrounds fb = removeFrameBackgrounds(cube, {}, progress, cancel);
  EXPECT_EQ(fb.framesSkipped, 0u);
  EXPECT_EQ(static_cast<float>(fb.restoredLevel), restored);
  for (int n = 0; n < nf; ++n) {
    const Result ref = withLibsep(frames[n], 64, 3, restored);
    EXPECT_EQ(static_cast<float>(fb.level[n]), ref.global) << "frame " << n;
    EXPECT_EQ(static_cast<float>(fb.rms[n]), ref.rms) << "frame " << n;
    std::size_t differ = 0;
    for (std::size_t i = 0; i < ref.pix.size(); ++i)
      differ += !sameFloat(cube.frame(n)[i], ref.pix[i]);
    EXPECT_EQ(differ, 0u) << "frame " << n;
  }
}

}  // namespace
}  // namespace st::stats
