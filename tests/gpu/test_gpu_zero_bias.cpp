// The stages from the per-pixel background to the residual means on one device-resident cube (issue 16:
// PreprocessAccelerator::zeroBias) against the CPU's stage-by-stage sequence (pipeline::zeroBiasStages
// without an accelerator):
//  - a drifting synthetic field (stars crossing the frame, a mask, cosmic-ray pixels, single-frame
//    transients, a mover kept): zero-biased pixels within 1e-5 relative (the per-pixel background holds
//    1e-6, the residual means 1e-6; star templates and subtraction use the CPU's arithmetic), and the
//    counts (pixels subtracted and zeroed by the star subtraction, whitened and excess positions, static,
//    unmeasured and single-frame zeroing per frame) and the star mask with its excess positions equal;
//  - pipeline::preprocess of a paper-neo-like cube (256^2 x 250, sky drifting 16.4 px/s, a saturated star)
//    with the CUDA accelerator and without: zero-biased cube within 1e-5 relative, the filtered cube within
//    the matched filter's tolerance (2e-5 sigma_F + 1e-5 of its largest |value|), the same stars, counts,
//    sigma_n and sigma_F, and the device's note in the notes;
//  - the noise model (stats::estimateNoiseModel) on the device, from the kept frames and from an upload:
//    frame scales, variance map and reference sigma equal to the CPU's (same order statistic); in the
//    pipeline within 1e-5 relative (its input cube differs by the stages' rounding).
//  - prefetch(): the cube uploaded behind the CPU stages is used by the next per-pixel background (note),
//    and not when that is another buffer or the same one changed meanwhile (results still the CPU's).
// Every test skips when no CUDA device is usable.
#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>
#include <cstring>
#include <memory>
#include <random>
#include <span>

#include "require_gpu_preprocess.hpp"
#include "st/common/error.hpp"
#include "st/gpu/preprocess.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/pipeline/preprocess_accelerator.hpp"
#include "st/sim/simulator.hpp"
#include "st/stack/matched_filter.hpp"
#include "st/psf/moffat.hpp"
#include "st/stats/background.hpp"
#include "st/stats/noise_model.hpp"

namespace st {
namespace {

constexpr Velocity kDrift{0.8, 0.1};  // px/s: 32 px over the 40 s span

struct StarAt {
  double x, y, amp;
};

const std::vector<StarAt> kStars = {
    {20.3, 15.7, 400.0}, {45.6, 40.2, 150.0}, {70.1, 20.9, 900.0}, {10.8, 50.4, 250.0}, {60.2, 55.5, 80.0}};

/// A drifting field: sky 100 + gradient, noise of sigma 2-4, Gaussian stars (sigma 1.3 px) moving with
/// kDrift (sub-pixel positions), cosmic rays, single-frame transients, a masked column and sparse masked
/// samples; times 0.5 s apart with jitter.
FrameCube driftingCube(int w, int h, int n, unsigned seed) {
  FrameCube c(w, h, static_cast<std::size_t>(n));
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int k = 0; k < n; ++k) {
    c.info()[k].mjdMid = 60000.0 + (0.5 * k + 0.05 * u(rng)) / kSecondsPerDay;
    c.info()[k].exposureS = 0.5;
  }
  const std::vector<double> dt = c.timeOffsetsS();
  for (int k = 0; k < n; ++k) {
    float* f = c.frame(k);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * w + x;
        double v = 100.0 + 0.05 * y + (2.0 + 2.0 * x / w) * g(rng);
        for (const StarAt& s : kStars) {
          const double dx = x - (s.x + kDrift.vx * dt[k]), dy = y - (s.y + kDrift.vy * dt[k]);
          v += s.amp * std::exp(-(dx * dx + dy * dy) / (2 * 1.3 * 1.3));
        }
        f[i] = static_cast<float>(v);
      }
    if (k % 9 == 4) f[static_cast<std::size_t>(10 + k % 40) * w + 30 + k % 50] += 300.0f;  // a transient
  }
  c.mask().assign(c.pixels().size(), 0);
  for (std::size_t i = 0; i < c.mask().size(); i += 131)
    c.mask()[i] = 1;
  for (int k = 0; k < n; ++k)
    for (int y = 0; y < h; ++y)
      c.mask()[static_cast<std::size_t>(k) * c.framePixels() + static_cast<std::size_t>(y) * w + 5] = 1;
  return c;
}

void disc(MovingMask& m, double cx, double cy, int r) {
  for (int y = static_cast<int>(cy) - r; y <= static_cast<int>(cy) + r; ++y)
    for (int x = static_cast<int>(cx) - r; x <= static_cast<int>(cx) + r; ++x)
      if ((x - cx) * (x - cx) + (y - cy) * (y - cy) <= r * r) m.set(x, y);
}

std::size_t mismatches(std::span<const float> a, std::span<const float> b, double tol, std::size_t* first) {
  std::size_t bad = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double d = std::fabs(double(a[i]) - double(b[i]));
    if (!(d <= tol * std::max(1.0, std::fabs(double(b[i]))))) {
      if (bad++ == 0) *first = i;
    }
  }
  return bad;
}

TEST(GpuZeroBias, StagesOnTheDeviceMatchTheCpuStages) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  const FrameCube raw = driftingCube(96, 64, 80, 3);
  // The stars' wide footprints (subtracted), their cores (zeroed), a mover left for the search.
  MovingMask region(raw, kDrift), cores(raw, kDrift), movers(raw, Velocity{-0.3, 0.2});
  for (const StarAt& s : kStars) {
    disc(region, s.x, s.y, 5);
    disc(cores, s.x, s.y, 1);
  }
  disc(movers, 40.0, 30.0, 2);
  MovingMask exclude = region;
  for (const StarAt& s : kStars)
    disc(exclude, s.x, s.y, 6);
  std::vector<std::uint64_t> crPixels;
  for (std::uint64_t i = 17; i < raw.pixels().size(); i += 40111)
    crPixels.push_back(i);

  pipeline::ZeroBiasInputs in;
  in.background.moverWindowFraction = 0.25;
  in.background.noiseMap = true;
  in.exclude = &exclude;
  in.subtractRegion = &region;
  in.cosmicRayPixels = &crPixels;
  in.moverMask = &movers;
  in.singleFrameSnr = 5.0;
  in.singleFrameRadiusPx = 3;
  in.residualMeshPx = 32;

  FrameCube cpu = raw, gpu = raw;
  MovingMask cpuCores = cores, gpuCores = cores;
  NullProgress p;
  CancelToken c;
  std::vector<std::string> notes;
  in.starMask = &cpuCores;
  const pipeline::ZeroBiasResult a = pipeline::zeroBiasStages(nullptr, cpu, in, p, c, notes);
  in.starMask = &gpuCores;
  pipeline::ZeroBiasResult b;
  {
    const std::shared_ptr<void> guard = accel->prefetch(gpu);  // uploaded behind "the CPU stages"
    ASSERT_TRUE(accel->zeroBias(gpu, in, b, p, c));
  }
  EXPECT_NE(accel->lastNote().find("download queued behind the next stages"), std::string::npos)
      << accel->lastNote();
  // The host cube's download may still run: waited for before the cube is read.
  accel->finishHostCopies();
  EXPECT_NE(accel->lastNote().find("kept on the device"), std::string::npos) << accel->lastNote();
  EXPECT_NE(accel->lastNote().find("prefetched behind the CPU stages"), std::string::npos)
      << accel->lastNote();

  ASSERT_TRUE(a.starsAttempted);
  ASSERT_TRUE(a.starSubtraction.applied);
  EXPECT_TRUE(b.starsAttempted);
  EXPECT_TRUE(b.starSubtraction.applied);
  EXPECT_GT(a.starSubtraction.pixelsSubtracted, 0u);
  EXPECT_EQ(b.starSubtraction.pixelsSubtracted, a.starSubtraction.pixelsSubtracted);
  EXPECT_EQ(b.starSubtraction.pixelsZeroed, a.starSubtraction.pixelsZeroed);
  EXPECT_EQ(b.starSubtraction.whitenedPositions, a.starSubtraction.whitenedPositions);
  EXPECT_EQ(b.starSubtraction.excessPositions, a.starSubtraction.excessPositions);
  EXPECT_NEAR(b.starSubtraction.meanTemplateFrames, a.starSubtraction.meanTemplateFrames, 1e-9);
  EXPECT_EQ(b.starSubtraction.excess.canvas(), a.starSubtraction.excess.canvas());
  EXPECT_EQ(gpuCores.canvas(), cpuCores.canvas());
  EXPECT_GT(a.staticPixelsZeroed, 0u);
  EXPECT_EQ(b.staticPixelsZeroed, a.staticPixelsZeroed);
  EXPECT_EQ(b.unmeasuredPixelsZeroed, a.unmeasuredPixelsZeroed);
  EXPECT_EQ(b.singleFrame.seedsPerFrame, a.singleFrame.seedsPerFrame);
  EXPECT_EQ(b.singleFrame.zeroedPerFrame, a.singleFrame.zeroedPerFrame);
  std::size_t seeds = 0;
  for (auto s : a.singleFrame.seedsPerFrame)
    seeds += s;
  EXPECT_GT(seeds, 0u);
  EXPECT_NEAR(b.background.sigmaN, a.background.sigmaN, 1e-9 * a.background.sigmaN);
  EXPECT_NEAR(b.residualMeanRms, a.residualMeanRms, 1e-6 * std::max(1e-3, a.residualMeanRms));
  std::size_t first = 0;
  const std::size_t bad = mismatches(gpu.pixels(), cpu.pixels(), 1e-5, &first);
  EXPECT_EQ(bad, 0u) << "first at " << first << ": " << gpu.pixels()[first] << " vs " << cpu.pixels()[first];
  std::vector<std::string> names;
  for (const auto& [stage, s] : b.stageSeconds)
    names.push_back(stage);
  EXPECT_EQ(names, (std::vector<std::string>{"per-pixel background", "star subtraction", "zeroing",
                                             "residual means"}));

  // The noise model: frame scales from the frames kept on the device, then from an upload (another
  // cube): the CPU's values exactly (the same variance map, the same order statistic).
  stats::NoiseModelParams np;
  const stats::NoiseModel cpuKept =
      stats::estimateNoiseModel(gpu, b.background.sigma, b.background.filled, np, c);
  const stats::NoiseModel devKept =
      accel->estimateNoiseModel(gpu, b.background.sigma, b.background.filled, np, c);
  EXPECT_NE(accel->lastNote().find("frames already on the device"), std::string::npos) << accel->lastNote();
  EXPECT_EQ(devKept.frameScale, cpuKept.frameScale);
  EXPECT_EQ(devKept.variance.pixels, cpuKept.variance.pixels);
  EXPECT_EQ(devKept.sigmaRef, cpuKept.sigmaRef);
  const stats::NoiseModel cpuUp =
      stats::estimateNoiseModel(cpu, a.background.sigma, a.background.filled, np, c);
  const stats::NoiseModel devUp =
      accel->estimateNoiseModel(cpu, a.background.sigma, a.background.filled, np, c);
  EXPECT_NE(accel->lastNote().find("upload"), std::string::npos) << accel->lastNote();
  EXPECT_EQ(devUp.frameScale, cpuUp.frameScale);
  EXPECT_EQ(devUp.sigmaRef, cpuUp.sigmaRef);
}

// The same 100 MB cube zero-biased twice on the device: once with its download waited for, once with it
// still running behind (its download is not over by the time a filter called next fails), and a destination
// of the right size for the filtered frames (the pipeline's case: downloaded launch by launch).
struct ZeroBiasedTwice {
  FrameCube raw, waited, behind, dest;
};
ZeroBiasedTwice zeroBiasTwice(pipeline::PreprocessAccelerator& accel, unsigned seed) {
  ZeroBiasedTwice t;
  t.raw = driftingCube(512, 256, 200, seed);
  t.waited = t.raw;
  t.behind = t.raw;
  const pipeline::ZeroBiasInputs in;
  NullProgress p;
  CancelToken c;
  pipeline::ZeroBiasResult a, b;
  EXPECT_TRUE(accel.zeroBias(t.waited, in, a, p, c));
  accel.finishHostCopies();
  EXPECT_TRUE(accel.zeroBias(t.behind, in, b, p, c));
  t.dest = FrameCube(t.raw.width(), t.raw.height(), 0);
  t.dest.pixels().resize(t.raw.pixels().size());
  return t;
}

bool sameBits(const FrameCube& a, const FrameCube& b) {
  return a.pixels().size() == b.pixels().size() &&
         std::memcmp(a.pixels().data(), b.pixels().data(), a.pixels().size() * sizeof(float)) == 0;
}

// A matched filter that fails (a kernel too large for the device: a GpuError before any launch) waits for the
// download behind it before the error leaves, so the CPU fallback reads whole frames: the cube equals the
// waited one, with no finishHostCopies() in between.
TEST(GpuZeroBias, FailedFilterWaitsForTheDownloadBehindIt) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  ZeroBiasedTwice t = zeroBiasTwice(*accel, 9);
  NullProgress p;
  CancelToken c;
  const stack::FilterKernel tooLarge = stack::makeFilterKernel(psf::Moffat::fromFwhm(10.5));
  EXPECT_THROW(accel->filterCubeFrom(t.behind, t.dest, tooLarge, p, c, nullptr, 0), GpuError);
  EXPECT_TRUE(sameBits(t.behind, t.waited));
  EXPECT_FALSE(sameBits(t.waited, t.raw));
}

// The same with a filter that is cancelled after its first launch: its buffers (the kept frames the
// zero-biased cube's download reads, the filtered frames it queued) are freed only once the copies are done,
// so the cancel comes out as such and the host cube is whole.
TEST(GpuZeroBias, CancelledFilterWaitsForTheDownloadBehindIt) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  ZeroBiasedTwice t = zeroBiasTwice(*accel, 10);
  NullProgress p;
  CancelToken stop;
  stop.cancel();
  const stack::FilterKernel kernel = stack::makeFilterKernel(psf::Moffat::fromFwhm(3.0));
  EXPECT_THROW(accel->filterCubeFrom(t.behind, t.dest, kernel, p, stop, nullptr, 0), Cancelled);
  EXPECT_TRUE(sameBits(t.behind, t.waited));
  accel->finishHostCopies();  // nothing left to fail
}

TEST(GpuZeroBias, PrefetchOfAnotherCubeIsNotUsed) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  const FrameCube raw = driftingCube(64, 48, 40, 5);
  FrameCube other = driftingCube(64, 48, 40, 6), cpu = raw, gpu = raw;
  stats::BackgroundParams params;
  NullProgress p;
  CancelToken c;
  const stats::Background a = stats::subtractPixelBackground(cpu, params, nullptr, p, c);
  stats::Background b;
  {
    const std::shared_ptr<void> guard = accel->prefetch(other);  // another buffer: uploaded, not used
    b = accel->subtractPixelBackground(gpu, params, nullptr, p, c);
  }
  EXPECT_EQ(accel->lastNote().find("prefetched"), std::string::npos) << accel->lastNote();
  EXPECT_NEAR(b.sigmaN, a.sigmaN, 1e-9 * a.sigmaN);
  std::size_t first = 0;
  EXPECT_EQ(mismatches(gpu.pixels(), cpu.pixels(), 1e-6, &first), 0u) << "first at " << first;
  // The same buffer changed after the prefetch (its sampled pixels): not used either.
  FrameCube changed = raw, cpu2 = raw;
  stats::Background b2;
  {
    const std::shared_ptr<void> guard = accel->prefetch(changed);
    for (float& v : changed.pixels())
      v += 1.0f;
    for (float& v : cpu2.pixels())
      v += 1.0f;
    b2 = accel->subtractPixelBackground(changed, params, nullptr, p, c);
  }
  EXPECT_EQ(accel->lastNote().find("prefetched"), std::string::npos) << accel->lastNote();
  const stats::Background a2 = stats::subtractPixelBackground(cpu2, params, nullptr, p, c);
  EXPECT_NEAR(b2.sigmaN, a2.sigmaN, 1e-9 * a2.sigmaN);
  EXPECT_EQ(mismatches(changed.pixels(), cpu2.pixels(), 1e-6, &first), 0u) << "first at " << first;
}

TEST(GpuZeroBias, PipelineWithTheDeviceMatchesTheCpu) {
  ST_REQUIRE_GPU_PREPROCESS(accel);
  NullProgress p;
  CancelToken c;
  sim::SimParams sp = sim::preset("paper-neo");
  sim::resize(sp, 256, 256, 250);
  sp.brightStars = 0;
  sp.starCount = 25;
  sp.fixedStars = {{100.0, 128.0, 10.5}};
  sim::SimResult sim = sim::simulate(sp, 11, p, c);
  pipeline::PreprocessParams params;
  params.masters = sim::exactMasters(sim);
  const pipeline::Prepared cpu = pipeline::preprocess(sim.cube, params, p, c);
  params.accelerator = accel.get();
  const pipeline::Prepared gpu = pipeline::preprocess(sim.cube, params, p, c);

  ASSERT_TRUE(cpu.starSubtraction.applied);
  EXPECT_TRUE(gpu.starSubtraction.applied);
  bool noted = false;
  for (const auto& n : gpu.notes)
    noted |= n.find("per-pixel background to residual means on") != std::string::npos;
  EXPECT_TRUE(noted);
  EXPECT_EQ(gpu.stars.size(), cpu.stars.size());
  EXPECT_EQ(gpu.starSubtraction.pixelsSubtracted, cpu.starSubtraction.pixelsSubtracted);
  EXPECT_EQ(gpu.starSubtraction.pixelsZeroed, cpu.starSubtraction.pixelsZeroed);
  EXPECT_EQ(gpu.starSubtraction.excessPositions, cpu.starSubtraction.excessPositions);
  EXPECT_EQ(gpu.starSubtraction.whitenedPositions, cpu.starSubtraction.whitenedPositions);
  EXPECT_EQ(gpu.staticPixelsZeroed, cpu.staticPixelsZeroed);
  EXPECT_EQ(gpu.unmeasuredPixelsZeroed, cpu.unmeasuredPixelsZeroed);
  EXPECT_EQ(gpu.singleFrame.zeroedPerFrame, cpu.singleFrame.zeroedPerFrame);
  EXPECT_EQ(gpu.cosmicRays, cpu.cosmicRays);
  // The cosmic rays' protection asked the device for its stacks (made there once the prefetch is uploaded).
  const bool crStacksNoted = std::any_of(gpu.notes.begin(), gpu.notes.end(), [](const std::string& n) {
    return n.find("cosmic rays: ") == 0 &&
           n.find(" of 3 protection stacks at the sky rate on cuda") != std::string::npos;
  });
  EXPECT_TRUE(crStacksNoted);
  EXPECT_NEAR(gpu.sigmaN, cpu.sigmaN, 1e-9 * cpu.sigmaN);
  EXPECT_NEAR(gpu.residualMeanRms, cpu.residualMeanRms, 1e-6 * std::max(1e-3, cpu.residualMeanRms));
  EXPECT_NEAR(gpu.filtered.sigmaF, cpu.filtered.sigmaF, 1e-4 * cpu.filtered.sigmaF);
  bool noiseNoted = false;
  for (const auto& n : gpu.notes)
    noiseNoted |= n.find("noise model on") != std::string::npos;
  EXPECT_TRUE(noiseNoted);
  // Both downloads ran behind the stages after them (the cubes are compared below).
  auto notedBoth = [&gpu](const char* a, const char* b) {
    return std::any_of(gpu.notes.begin(), gpu.notes.end(), [&](const std::string& n) {
      return n.find(a) != std::string::npos && n.find(b) != std::string::npos;
    });
  };
  EXPECT_TRUE(
      notedBoth("per-pixel background to residual means on", "download queued behind the next stages"));
  EXPECT_TRUE(notedBoth("noise model on", "frames already on the device"));
  EXPECT_TRUE(notedBoth("matched filter on", "download behind the launches"));
  ASSERT_EQ(gpu.noiseModel.frameScale.size(), cpu.noiseModel.frameScale.size());
  for (std::size_t n = 0; n < cpu.noiseModel.frameScale.size(); ++n)
    EXPECT_NEAR(gpu.noiseModel.frameScale[n], cpu.noiseModel.frameScale[n],
                1e-5 * cpu.noiseModel.frameScale[n])
        << "frame " << n;
  EXPECT_NEAR(gpu.noiseModel.sigmaRef, cpu.noiseModel.sigmaRef, 1e-5 * cpu.noiseModel.sigmaRef);
  std::size_t first = 0;
  const std::size_t bad = mismatches(gpu.frames.pixels(), cpu.frames.pixels(), 1e-5, &first);
  EXPECT_EQ(bad, 0u) << "zero-biased cube, first at " << first << ": " << gpu.frames.pixels()[first] << " vs "
                     << cpu.frames.pixels()[first];
  double maxAbs = 0.0;
  for (float v : cpu.filtered.frames.pixels())
    maxAbs = std::max(maxAbs, std::fabs(double(v)));
  const double tol = 2e-5 * cpu.filtered.sigmaF + 1e-5 * maxAbs;
  std::size_t badF = 0;
  for (std::size_t i = 0; i < cpu.filtered.frames.pixels().size(); ++i)
    if (!(std::fabs(double(gpu.filtered.frames.pixels()[i]) - cpu.filtered.frames.pixels()[i]) <= tol))
      ++badF;
  EXPECT_EQ(badF, 0u) << "filtered cube, tolerance " << tol;
}

}  // namespace
}  // namespace st
