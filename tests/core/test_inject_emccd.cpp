// Injection into EMCCD frames (core/inject): the signal's photo-electrons go through the EM register as the
// simulator renders its own sources, so a mover injected into EMCCD frames has their noise.
#include <gtest/gtest.h>

#include <cstdio>
#include <vector>

#include "inject_fixture.hpp"

namespace st::inject {
namespace {

using fixture::makeSimField;
using fixture::SimField;
using fixture::smallParams;

// An EMCCD's injected signal goes through the EM register as the simulator's own sources do: per pixel, the
// variance is 2 x EMGAIN / GAIN times the expected counts (a CCD's: 1 / GAIN), and the mean the expected
// counts. Before 2026-12-05 an EMCCD's signal had a CCD's Poisson noise at GAIN: EMGAIN x 2 too little
// variance (a mover injected into the paper's EMCCD frames looked 20 times less noisy than it is).
TEST(Inject, EmccdSignalHasTheEmRegistersExcessNoise) {
  const SimField s = makeSimField(3);
  CancelToken c;
  InjectParams params = smallParams(5);
  params.snrMin = 80.0;
  params.snrMax = 100.0;
  const InjectionPlan plan = planInjection(s.calibrated, s.field, params, c);
  RawGeometry g = rawGeometry(s.sim.cube, s.masters, {});
  EXPECT_EQ(g.emGain, 1.0);  // "small" is a CCD; an EMGAIN keyword sets it (below)
  g.integerCounts = false;
  std::vector<Image> expected;
  for (std::size_t n = 0; n < s.sim.cube.frameCount(); ++n)
    expected.push_back(rawSignal(plan, n, g));  // no gain: the expected counts
  const double gain = 2.0;
  for (const double em : {1.0, 50.0}) {
    g.gainEPerAdu = gain;
    g.emGain = em;
    double sumSq = 0.0, sumE = 0.0, sumD = 0.0;
    InjectionPlan draw = plan;
    for (std::uint64_t repeat = 0; repeat < 16; ++repeat) {  // 16 noise draws: the mean to ~0.8%
      draw.params.seed = plan.params.seed + 1000 * repeat;
      for (std::size_t n = 0; n < expected.size(); ++n) {
        const Image v = rawSignal(draw, n, g);
        for (std::size_t i = 0; i < v.size(); ++i) {
          const double e = expected[n].pixels[i];
          if (!(e > 0.0)) continue;
          const double d = v.pixels[i] - e;
          sumSq += d * d;
          sumD += d;
          sumE += e;
        }
      }
    }
    const double perCount = em > 1.0 ? 2.0 * em / gain : 1.0 / gain;
    std::printf("EM gain %g: variance per expected count %.4f (model %.4f), mean offset %.2e of the counts\n",
                em, sumSq / sumE, perCount, sumD / sumE);
    EXPECT_NEAR(sumSq / sumE / perCount, 1.0, 0.05) << "EM gain " << em;
    EXPECT_NEAR(sumD / sumE, 0.0, 0.02) << "EM gain " << em;
  }
  FrameCube withEm = s.sim.cube;
  withEm.header.setNumber("EMGAIN", 300.0, "");
  EXPECT_EQ(rawGeometry(withEm, s.masters, {}).emGain, 300.0);
}

}  // namespace
}  // namespace st::inject
