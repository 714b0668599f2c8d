// The pipeline's device hook (st/pipeline/preprocess_accelerator.hpp): a device that fails (st::GpuError)
// leaves the stage to the CPU, with a warning naming the stage and the device's message, and the result is
// the CPU's; a device that works is used; other errors are not swallowed. The sky-rate stacks' provider (a
// device's detect::SkyStackCache::Provider) is used when it makes a stack, the CPU stacks when it makes none.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <future>
#include <optional>
#include <random>
#include <set>
#include <stdexcept>
#include <thread>

#include "st/calib/calibration.hpp"
#include "st/common/error.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/sim/simulator.hpp"
#include "st/detect/sky_stack.hpp"
#include "st/pipeline/preprocess_accelerator.hpp"
#include "st/psf/moffat.hpp"
#include "st/stats/noise_model.hpp"

namespace st {
namespace {

class FakeAccelerator final : public pipeline::PreprocessAccelerator {
 public:
  enum class Mode { Fail, Work, InputFault };
  explicit FakeAccelerator(Mode m) : m_mode(m) {}
  std::string name() const override { return "fake device"; }
  stats::Background subtractPixelBackground(FrameCube& cube, const stats::BackgroundParams& params,
                                            const detect::MovingMask* exclude, ProgressSink& progress,
                                            CancelToken& cancel) override {
    ++calls;
    act();
    return stats::subtractPixelBackground(cube, params, exclude, progress, cancel);
  }
  stack::MatchedFilterResult filterCube(FrameCube& cube, const stack::FilterKernel& kernel,
                                        ProgressSink& progress, CancelToken& cancel,
                                        const stats::NoiseModel* noise, std::uint64_t) override {
    ++calls;
    act();
    return stack::filterCube(cube, kernel, progress, cancel, noise);
  }
  stats::FrameBackgrounds removeFrameBackgrounds(FrameCube& cube, const stats::FrameBackgroundParams& params,
                                                 ProgressSink& progress, CancelToken& cancel) override {
    ++calls;
    act();
    return stats::removeFrameBackgrounds(cube, params, progress, cancel);
  }
  double removeResidualMeans(FrameCube& cube, int meshPx, double clipSigma, ProgressSink& progress,
                             CancelToken& cancel) override {
    ++calls;
    act();
    return stats::removeResidualMeans(cube, meshPx, clipSigma, progress, cancel);
  }
  std::optional<detect::SkyStack> skyStack(const FrameCube& cube, Velocity rate, double subtract,
                                           std::size_t first, std::size_t last) override {
    ++stackCalls;
    act();
    if (!makeStacks) return std::nullopt;  // a working device that declines: the CPU stacks
    // One that makes them (the CPU's stacks), from whichever thread asks.
    stackThreads.insert(std::this_thread::get_id());
    NullProgress p;
    CancelToken c;
    return detect::stackAtSkyRate(cube, rate, subtract, p, c, first, last);
  }
  std::optional<std::vector<float>> filteredSnr(const detect::FilteredSnrInputs&) override {
    ++snrCalls;
    act();
    return std::nullopt;  // a working device that declines: the CPU makes the map
  }
  std::optional<std::vector<detect::PhasePeak>> phaseCorrelations(
      const detect::PhaseCorrelationBatch&) override {
    ++phaseCalls;
    act();
    return std::nullopt;  // a working device that declines: the CPU correlates
  }
  bool zeroBias(FrameCube& cube, const pipeline::ZeroBiasInputs& in, pipeline::ZeroBiasResult&, ProgressSink&,
                CancelToken&) override {
    ++calls;
    (void)cube;
    if (in.starMask) in.starMask->set(in.starMask->x0(), in.starMask->y0());  // restored by zeroBiasOn
    act();
    return false;  // not supported: the stages one by one
  }
  /// Fail and InputFault as every stage; Work: the CPU's pixel calibration, then SEP, after
  /// `declineCalibration` none (not supported).
  std::optional<stats::FrameBackgrounds> calibrateAndRemoveFrameBackgrounds(
      FrameCube& cube, const calib::CalibrationPlan& plan, const stats::FrameBackgroundParams& params,
      ProgressSink& progress, CancelToken& cancel) override {
    ++calibrationCalls;
    act();
    if (declineCalibration) return std::nullopt;
    calib::applyPixelCalibration(cube, plan, progress, cancel);
    return stats::removeFrameBackgrounds(cube, params, progress, cancel);
  }
  int calls = 0, snrCalls = 0, stackCalls = 0, calibrationCalls = 0, phaseCalls = 0;
  bool declineCalibration = false;
  bool makeStacks = false;
  std::set<std::thread::id> stackThreads;

 private:
  void act() const {
    if (m_mode == Mode::Fail) throw GpuError("cudaMalloc(1610612736 bytes) failed: out of memory");
    if (m_mode == Mode::InputFault) throw InputError("bad input");
  }
  Mode m_mode;
};

FrameCube noiseCube(int w, int h, int n) {
  FrameCube c(w, h, static_cast<std::size_t>(n));
  std::mt19937 rng(5);
  std::normal_distribution<float> g(100.0f, 3.0f);
  for (auto& p : c.pixels())
    p = g(rng);
  for (int k = 0; k < n; ++k)
    c.info()[k].mjdMid = 60000.0 + k / 86400.0;
  return c;
}

TEST(PreprocessAccelerator, DeviceFailureFallsBackToTheCpuWithAWarning) {
  FakeAccelerator fail(FakeAccelerator::Mode::Fail);
  NullProgress progress;
  CancelToken cancel;
  FrameCube a = noiseCube(48, 40, 30), b = a;
  std::vector<std::string> notes;
  const stats::Background ra =
      pipeline::subtractPixelBackgroundOn(&fail, a, {}, nullptr, progress, cancel, notes);
  const stats::Background rb = stats::subtractPixelBackground(b, {}, nullptr, progress, cancel);
  EXPECT_EQ(fail.calls, 1);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("per-pixel background on fake device failed"), std::string::npos) << notes[0];
  EXPECT_NE(notes[0].find("out of memory"), std::string::npos) << notes[0];
  EXPECT_EQ(a.pixels(), b.pixels());
  EXPECT_EQ(ra.level.pixels, rb.level.pixels);

  const stack::FilterKernel k = stack::makeFilterKernel(psf::Moffat::fromFwhm(2.0));
  FrameCube fa = a, fb = a;
  const auto ma = pipeline::filterCubeOn(&fail, fa, k, progress, cancel, nullptr, notes);
  const auto mb = stack::filterCube(fb, k, progress, cancel, nullptr);
  ASSERT_EQ(notes.size(), 2u);
  EXPECT_NE(notes[1].find("matched filter on fake device failed"), std::string::npos) << notes[1];
  EXPECT_EQ(fa.pixels(), fb.pixels());
  EXPECT_EQ(ma.sigmaF, mb.sigmaF);

  FrameCube za = fa, zb = fa;
  const double rmsA = pipeline::removeResidualMeansOn(&fail, za, 16, 5.0, progress, cancel, notes);
  const double rmsB = stats::removeResidualMeans(zb, 16, 5.0, progress, cancel);
  ASSERT_EQ(notes.size(), 3u);
  EXPECT_NE(notes[2].find("residual means on fake device failed"), std::string::npos) << notes[2];
  EXPECT_EQ(za.pixels(), zb.pixels());
  EXPECT_EQ(rmsA, rmsB);

  FrameCube sa = noiseCube(48, 40, 30), sb = sa;
  const auto la = pipeline::removeFrameBackgroundsOn(&fail, sa, {}, progress, cancel, notes);
  const auto lb = stats::removeFrameBackgrounds(sb, {}, progress, cancel);
  ASSERT_EQ(notes.size(), 4u);
  EXPECT_NE(notes[3].find("frame backgrounds on fake device failed"), std::string::npos) << notes[3];
  EXPECT_EQ(sa.pixels(), sb.pixels());
  EXPECT_EQ(la.level, lb.level);
}

// The pixel calibration with the frame backgrounds (calibrateAndRemoveFrameBackgroundsOn): a device that
// fails leaves the cube raw, and the CPU calibrates it and removes the backgrounds, with a warning; one that
// declines or works gives the same cube; either way the cube equals applyCalibration's followed by the CPU's
// frame backgrounds.
TEST(PreprocessAccelerator, CalibrationWithTheFrameBackgroundsFallsBackToTheCpu) {
  const FrameCube raw = noiseCube(48, 40, 12);
  calib::MasterCalibration m;
  m.width = 48;
  m.height = 40;
  m.bias = Image(48, 40, 20.0f);
  m.flat = Image(48, 40, 0.95f);
  m.flat.pixels[7] = 1.1f;
  NullProgress progress;
  CancelToken cancel;
  FrameCube want = raw;
  calib::applyCalibration(want, m, {}, progress, cancel);
  stats::removeFrameBackgrounds(want, {}, progress, cancel);
  ASSERT_NE(want.pixels(), raw.pixels());
  for (const auto mode : {FakeAccelerator::Mode::Fail, FakeAccelerator::Mode::Work}) {
    for (const bool decline : {false, true}) {
      FakeAccelerator accel(mode);
      accel.declineCalibration = decline;
      FrameCube cube = raw;
      calib::CalibrationPlan plan = calib::planCalibration(cube, m, {});
      std::vector<std::string> notes;
      pipeline::calibrateAndRemoveFrameBackgroundsOn(&accel, cube, plan, {}, progress, cancel, notes);
      EXPECT_EQ(accel.calibrationCalls, 1);
      EXPECT_EQ(cube.pixels(), want.pixels());
      if (mode == FakeAccelerator::Mode::Fail) {
        ASSERT_EQ(notes.size(), 1u);
        EXPECT_NE(notes[0].find("calibration and frame backgrounds on fake device failed"), std::string::npos)
            << notes[0];
        EXPECT_EQ(accel.calls, 0);  // the backgrounds not asked of the failed device again
      } else {
        EXPECT_TRUE(notes.empty());
        EXPECT_EQ(accel.calls, decline ? 1 : 0);  // declined: the device's own frame backgrounds
      }
    }
  }
  // finishCalibration before the pixels (the device's order when nothing is trimmed): the same cube and mask.
  m.bad.assign(48 * 40, 0);
  m.bad[100] = 1;
  FrameCube a = raw, b = raw;
  calib::applyCalibration(a, m, {}, progress, cancel);
  calib::CalibrationPlan plan = calib::planCalibration(b, m, {});
  EXPECT_FALSE(calib::trims(b, plan));
  const calib::CalibrationReport rep = calib::finishCalibration(b, m, plan);
  calib::applyPixelCalibration(b, plan, progress, cancel);
  EXPECT_EQ(a.pixels(), b.pixels());
  EXPECT_EQ(a.mask(), b.mask());
  EXPECT_EQ(rep.badPixels, 1u);
  EXPECT_EQ(b.mask()[5 * 48 * 40 + 100], 1);
}

TEST(PreprocessAccelerator, WorkingDeviceIsUsedAndInputErrorsPropagate) {
  NullProgress progress;
  CancelToken cancel;
  std::vector<std::string> notes;
  FakeAccelerator work(FakeAccelerator::Mode::Work);
  FrameCube a = noiseCube(48, 40, 30);
  pipeline::subtractPixelBackgroundOn(&work, a, {}, nullptr, progress, cancel, notes);
  EXPECT_EQ(work.calls, 1);
  EXPECT_TRUE(notes.empty());
  FakeAccelerator bad(FakeAccelerator::Mode::InputFault);
  EXPECT_THROW(pipeline::subtractPixelBackgroundOn(&bad, a, {}, nullptr, progress, cancel, notes),
               InputError);
  // No device: the CPU, silently.
  EXPECT_NO_THROW(pipeline::subtractPixelBackgroundOn(nullptr, a, {}, nullptr, progress, cancel, notes));
  EXPECT_TRUE(notes.empty());
}

// filterCubeFromOn (the pipeline's matched filter of the zero-biased cube into the filtered one): the source
// is left alone, a working device (here the interface's default: copy, then filterCube) and a failing one
// (the CPU, with a warning) both give the CPU filter of a copy of the source's pixels, unmasked.
TEST(PreprocessAccelerator, FilterFromSourceLeavesItAndMatchesTheCpuOnACopy) {
  NullProgress progress;
  CancelToken cancel;
  FrameCube source = noiseCube(48, 40, 30);
  source.mask().assign(source.pixels().size(), 0);
  source.mask()[100] = 1;  // not used: masked samples of a zero-biased cube are 0 already
  const FrameCube before = source;
  const stack::FilterKernel k = stack::makeFilterKernel(psf::Moffat::fromFwhm(2.0));
  FrameCube ref = source;
  ref.mask().clear();
  const auto mr = stack::filterCube(ref, k, progress, cancel, nullptr);
  for (const auto mode : {FakeAccelerator::Mode::Work, FakeAccelerator::Mode::Fail}) {
    FakeAccelerator accel(mode);
    std::vector<std::string> notes;
    FrameCube out(source.width(), source.height(), 0);
    out.info() = source.info();
    const auto m = pipeline::filterCubeFromOn(&accel, source, out, k, progress, cancel, nullptr, notes, 7);
    EXPECT_EQ(accel.calls, 1);
    EXPECT_EQ(notes.size(), mode == FakeAccelerator::Mode::Fail ? 1u : 0u);
    EXPECT_EQ(out.pixels(), ref.pixels());
    EXPECT_TRUE(out.mask().empty());
    EXPECT_EQ(m.sigmaF, mr.sigmaF);
    EXPECT_EQ(source.pixels(), before.pixels());
    EXPECT_EQ(source.mask(), before.mask());
  }
}

TEST(PreprocessAccelerator, ZeroBiasDeviceFailureRestoresTheStarMaskAndRunsTheStages) {
  const FrameCube raw = noiseCube(40, 30, 24);
  MovingMask stars(raw, Velocity{0.5, 0.0}), movers(raw, Velocity{-0.2, 0.1});
  for (int y = 12; y < 16; ++y)
    for (int x = 10; x < 14; ++x)
      stars.set(x, y);
  movers.set(25, 20);
  const MovingMask starsBefore = stars;
  std::vector<std::uint64_t> cr = {5, 1234, 20000};
  pipeline::ZeroBiasInputs in;
  in.background.maxFrames = 24;
  in.cosmicRayPixels = &cr;
  in.starMask = &stars;
  in.moverMask = &movers;
  in.residualMeshPx = 16;
  NullProgress p;
  CancelToken c;
  FrameCube cpu = raw, dev = raw;
  std::vector<std::string> cpuNotes, notes;
  const pipeline::ZeroBiasResult a = pipeline::zeroBiasStages(nullptr, cpu, in, p, c, cpuNotes);
  EXPECT_TRUE(cpuNotes.empty());
  MovingMask cpuStars = stars;
  stars = starsBefore;
  FakeAccelerator fail(FakeAccelerator::Mode::Fail);
  const pipeline::ZeroBiasResult b = pipeline::zeroBiasOn(&fail, dev, in, p, c, notes);
  EXPECT_EQ(stars.canvas(), cpuStars.canvas());  // the failed device's change undone
  EXPECT_EQ(dev.pixels(), cpu.pixels());
  EXPECT_EQ(b.staticPixelsZeroed, a.staticPixelsZeroed);
  EXPECT_GT(a.staticPixelsZeroed, 0u);
  EXPECT_EQ(b.singleFrame.zeroedPerFrame, a.singleFrame.zeroedPerFrame);
  EXPECT_DOUBLE_EQ(b.residualMeanRms, a.residualMeanRms);
  ASSERT_FALSE(notes.empty());
  EXPECT_NE(notes.front().find("per-pixel background to residual means on fake device failed"),
            std::string::npos)
      << notes.front();
  EXPECT_EQ(fail.calls, 3);  // zeroBias, then the per-pixel background and residual means (both failing)
  EXPECT_EQ(b.stageSeconds.size(), 3u);  // no star subtraction without a region
}

// The small simulated observation (seed 3), its parameters (the exact masters) and its CPU pre-processing:
// made once for the tests that compare a device's pre-processing with it.
struct SmallReference {
  sim::SimResult sim;
  pipeline::PreprocessParams params;
  pipeline::Prepared cpu;
};
const SmallReference& smallReference() {
  static const SmallReference ref = [] {
    NullProgress p;
    CancelToken c;
    SmallReference r;
    r.sim = sim::simulate(sim::preset("small"), 3, p, c);
    r.params.masters = sim::exactMasters(r.sim);
    r.cpu = pipeline::preprocess(r.sim.cube, r.params, p, c);
    return r;
  }();
  return ref;
}

// The static sources' filtered SNR maps (PreprocessAccelerator::filteredSnr) and the stacks at the sky rate
// (skyStack) and the sky rate's phase correlations (phaseCorrelations) in pipeline::preprocess: a device that
// fails is asked once, warned about once and then left alone; one that declines is asked for every map, stack
// and group of links; either way the stars and the sky rate are the CPU's.
TEST(PreprocessAccelerator, FilteredSnrFailureWarnsOnceAndTheStarsAreTheCpus) {
  NullProgress p;
  CancelToken c;
  const SmallReference& ref = smallReference();
  const sim::SimResult& sim = ref.sim;
  pipeline::PreprocessParams params = ref.params;
  const pipeline::Prepared& cpu = ref.cpu;
  FakeAccelerator fail(FakeAccelerator::Mode::Fail), decline(FakeAccelerator::Mode::Work);
  for (FakeAccelerator* accel : {&fail, &decline}) {
    SCOPED_TRACE(accel == &fail ? "failing" : "declining");
    params.accelerator = accel;
    const pipeline::Prepared dev = pipeline::preprocess(sim.cube, params, p, c);
    ASSERT_EQ(dev.stars.size(), cpu.stars.size());
    for (std::size_t i = 0; i < cpu.stars.size(); ++i) {
      EXPECT_EQ(dev.stars[i].x, cpu.stars[i].x) << i;
      EXPECT_EQ(dev.stars[i].filteredSnr, cpu.stars[i].filteredSnr) << i;
    }
    const auto count = [&](const char* text) {
      return std::count_if(dev.notes.begin(), dev.notes.end(),
                           [&](const std::string& n) { return n.find(text) != std::string::npos; });
    };
    EXPECT_EQ(count("warning: the static sources' filtered SNR fell back to the CPU (fake device: "),
              accel == &fail ? 1 : 0);
    EXPECT_EQ(count("(0 on the device)"), 1);
    // The stacks at the sky rate (the cosmic rays' protection, the static sources, the PSF) likewise.
    EXPECT_EQ(count("warning: the stacks at the sky rate fell back to the CPU (fake device: "),
              accel == &fail ? 1 : 0);
    if (accel == &fail) {
      EXPECT_EQ(accel->stackCalls, 1);
    } else {
      EXPECT_GE(accel->stackCalls, 3);  // the cosmic rays' three protection stacks at least
    }
    // Failing: asked once, then left alone. Declining: asked for every map (the stack's two analyses at
    // least).
    if (accel == &fail) {
      EXPECT_EQ(accel->snrCalls, 1);
    } else {
      EXPECT_GE(accel->snrCalls, 2);
    }
    // The sky rate's chain phase correlations likewise: the CPU's rate, a warning once when failing, every
    // group of links asked when declining.
    EXPECT_EQ(dev.skyRate, cpu.skyRate);
    EXPECT_EQ(count("warning: the sky rate's phase correlations fell back to the CPU (fake device: "),
              accel == &fail ? 1 : 0);
    EXPECT_EQ(count("sky rate: the chain's phase correlations, 0 of "), 1);
    if (accel == &fail) {
      EXPECT_EQ(accel->phaseCalls, 1);
    } else {
      EXPECT_GE(accel->phaseCalls, 1);
    }
  }
}

TEST(SkyStackCache, ProviderStacksAreUsedAndNoneFallsBackToTheCpu) {
  const FrameCube c = noiseCube(48, 40, 30);
  NullProgress progress;
  CancelToken cancel;
  const Velocity rate{0.5, -0.2};
  detect::SkyStackCache cache;
  int asked = 0;
  cache.setProvider([&](const FrameCube& cube, Velocity v, double subtract, std::size_t first,
                        std::size_t last) -> std::optional<detect::SkyStack> {
    ++asked;
    EXPECT_NE(last, 0u);  // resolved
    if (first != 0) return std::nullopt;
    detect::SkyStack s = detect::stackAtSkyRate(cube, v, subtract, progress, cancel, first, last);
    s.mean.pixels[0] = 12345.0f;  // a marker: this stack is the provider's
    return s;
  });
  EXPECT_EQ(cache.stack(c, rate, 100.0, progress, cancel).mean.pixels[0], 12345.0f);
  const detect::SkyStack cpu = detect::stackAtSkyRate(c, rate, 100.0, progress, cancel, 10, 20);
  EXPECT_EQ(cache.stack(c, rate, 100.0, progress, cancel, 10, 20).mean.pixels, cpu.mean.pixels);
  EXPECT_EQ(cache.stack(c, rate, 100.0, progress, cancel, 0, 30).mean.pixels[0], 12345.0f);  // cached
  EXPECT_EQ(asked, 2);
  EXPECT_EQ(cache.made(), 2);
  EXPECT_EQ(cache.provided(), 1);
}

// Stacks at the sky rate made by a device on threads of their own (issue 16: the cosmic rays' protection
// stacks beside the wait for the frames' download, the static sources' thirds and halves beside their
// analysis) are the stacks asked for: the cosmic rays, stars and PSF are the CPU's, to the bit.
TEST(PreprocessAccelerator, StacksMadeAheadOnOtherThreadsGiveTheCpusResults) {
  NullProgress p;
  CancelToken c;
  const SmallReference& ref = smallReference();
  const sim::SimResult& sim = ref.sim;
  pipeline::PreprocessParams params = ref.params;
  const pipeline::Prepared& cpu = ref.cpu;
  FakeAccelerator dev(FakeAccelerator::Mode::Work);
  dev.makeStacks = true;
  params.accelerator = &dev;
  const pipeline::Prepared got = pipeline::preprocess(sim.cube, params, p, c);
  EXPECT_EQ(got.cosmicRayPixels, cpu.cosmicRayPixels);
  EXPECT_GT(cpu.cosmicRayPixels.size(), 0u);
  ASSERT_EQ(got.stars.size(), cpu.stars.size());
  for (std::size_t i = 0; i < cpu.stars.size(); ++i) {
    EXPECT_EQ(got.stars[i].x, cpu.stars[i].x) << i;
    EXPECT_EQ(got.stars[i].y, cpu.stars[i].y) << i;
    EXPECT_EQ(got.stars[i].flux, cpu.stars[i].flux) << i;
  }
  EXPECT_EQ(got.movers.size(), cpu.movers.size());
  EXPECT_EQ(got.psf.radius, cpu.psf.radius);
  EXPECT_EQ(got.psf.beta, cpu.psf.beta);
  EXPECT_EQ(got.sigmaN, cpu.sigmaN);
  // The protection's three stacks and the search's thirds (its halves only where a faint source needs them)
  // came from threads other than this one; the full stack from this one.
  EXPECT_GE(dev.stackCalls, 3 + 1 + 3);
  EXPECT_TRUE(std::any_of(dev.stackThreads.begin(), dev.stackThreads.end(),
                          [](std::thread::id t) { return t != std::this_thread::get_id(); }));
  const auto note = std::find_if(got.notes.begin(), got.notes.end(), [](const std::string& n) {
    return n.starts_with("cosmic rays: 3 of 3 protection stacks at the sky rate on fake device");
  });
  EXPECT_NE(note, got.notes.end());
  const auto stacks = std::find_if(got.notes.begin(), got.notes.end(), [](const std::string& n) {
    return n.find("of them beside the host work") != std::string::npos;
  });
  ASSERT_NE(stacks, got.notes.end());
  EXPECT_EQ(stacks->find(", 0 of them beside"), std::string::npos) << *stacks;
}

// A prefetch (issue 16: the static-source search's thirds and halves made on a device beside its host work)
// runs the provider on a thread of its own and returns at once; stack() hands out what it made, the CPU's
// stack where it declined, and its exception where it threw; the stacks are those asked for one by one.
TEST(SkyStackCache, PrefetchRunsTheProviderOnItsOwnThreadAndStackTakesWhatItMade) {
  const FrameCube c = noiseCube(48, 40, 30);
  NullProgress progress;
  CancelToken cancel;
  const Velocity rate{0.5, -0.2};
  detect::SkyStackCache cache;
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  std::atomic<int> asked{0};
  std::thread::id providerThread;
  cache.setProvider([&](const FrameCube& cube, Velocity v, double subtract, std::size_t first,
                        std::size_t last) -> std::optional<detect::SkyStack> {
    if (asked++ == 0) {
      released.wait();  // the caller goes on meanwhile
      providerThread = std::this_thread::get_id();
    }
    if (first == 5) throw std::runtime_error("provider fault");
    if (first != 0) return std::nullopt;
    detect::SkyStack s = detect::stackAtSkyRate(cube, v, subtract, progress, cancel, first, last);
    s.mean.pixels[0] = 12345.0f + static_cast<float>(last);  // the provider's, and which
    return s;
  });
  cache.prefetch(c, rate, 100.0, {{0, 10}, {10, 20}, {5, 15}, {0, 0}, {0, 30}});  // {0, 0} is {0, 30}
  // prefetch() returned while its thread's first call waits for the release.
  for (int i = 0; i < 5000 && asked.load() == 0; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_EQ(asked.load(), 1);
  release.set_value();
  EXPECT_EQ(cache.stack(c, rate, 100.0, progress, cancel, 0, 10).mean.pixels[0], 12355.0f);
  EXPECT_NE(providerThread, std::this_thread::get_id());
  const detect::SkyStack cpu = detect::stackAtSkyRate(c, rate, 100.0, progress, cancel, 10, 20);
  EXPECT_EQ(cache.stack(c, rate, 100.0, progress, cancel, 10, 20).mean.pixels, cpu.mean.pixels);
  EXPECT_THROW(cache.stack(c, rate, 100.0, progress, cancel, 5, 15), std::runtime_error);
  cache.settle();
  EXPECT_EQ(asked.load(), 5);  // one call a distinct range, and the one declined ahead asked again
  EXPECT_EQ(cache.stack(c, rate, 100.0, progress, cancel).mean.pixels[0], 12375.0f);
  EXPECT_EQ(cache.prefetched(), 2);
  EXPECT_EQ(cache.provided(), 2);
  EXPECT_EQ(cache.made(), 3);
  // Every range made already (or made by this prefetch): nothing new asked.
  cache.prefetch(c, rate, 100.0, {{0, 10}, {10, 20}, {0, 30}});
  cache.settle();
  EXPECT_EQ(asked.load(), 5);
  // A stack it made that was never asked for is kept by the next prefetch, and the provider is not asked
  // for it again.
  cache.prefetch(c, rate, 100.0, {{0, 20}});
  cache.settle();
  cache.prefetch(c, rate, 100.0, {{0, 20}, {0, 25}});
  cache.settle();
  EXPECT_EQ(asked.load(), 7);
  EXPECT_EQ(cache.stack(c, rate, 100.0, progress, cancel, 0, 20).mean.pixels[0], 12365.0f);
  EXPECT_EQ(cache.stack(c, rate, 100.0, progress, cancel, 0, 25).mean.pixels[0], 12370.0f);
  EXPECT_EQ(asked.load(), 7);
  EXPECT_EQ(cache.prefetched(), 4);
}

}  // namespace
}  // namespace st
