// The co-moving fit against the simulator's truth (issue 6, item 8) on the paper's presets, cut to 96x96
// around the object with stars, cosmic rays and hot pixels switched off and the frames zero-biased with the
// simulator's exact bias, flat and sky (the pre-processing stage is tested on its own): fitted positions and
// velocities within 3 sigma of the truth, SNR within 10% of the truth's expected SNR, magnitude within
// 0.1 mag.
#include <gtest/gtest.h>

#include <cmath>

#include "st/astro/photometry.hpp"
#include "st/fit/comoving_fit.hpp"
#include "st/sim/simulator.hpp"
#include "st/vet/segments.hpp"

namespace st::fit {
namespace {

struct Observation {
  sim::SimResult sim;
  FitOptions options;
};

Observation observe(const std::string& presetName, std::uint64_t seed) {
  sim::SimParams p = sim::preset(presetName);
  sim::resize(p, 96, 96, 0);
  p.starCount = 0;
  p.brightStars = 0;
  p.fixedStars.clear();
  p.cosmicRaysPerFrame = 0.0;
  p.hotPixels = 0;
  NullProgress progress;
  CancelToken cancel;
  Observation o{sim::simulate(p, seed, progress, cancel), {}};
  FrameCube& cube = o.sim.cube;
  for (std::size_t n = 0; n < cube.frameCount(); ++n) {
    float* f = cube.frame(n);
    for (std::size_t i = 0; i < cube.framePixels(); ++i) {
      f[i] = static_cast<float>((f[i] - o.sim.biasFrame.pixels[i]) / o.sim.flatFrame.pixels[i] -
                                o.sim.truth.skyAdu[n]);
    }
  }
  const sim::Truth& t = o.sim.truth;
  o.options.psf = {t.psfRadiusPx, t.psfBeta};
  o.options.sigmaN = t.noiseSigmaAdu[0];
  o.options.gain = 1.0 / t.aduPerPhoton;
  return o;
}

void expectMatchesTruth(const std::string& presetName) {
  const Observation o = observe(presetName, 3);
  const sim::Truth& t = o.sim.truth;
  ASSERT_EQ(t.objects.size(), 1u);
  const sim::TruthObject& obj = t.objects[0];
  // Start like a search cell: rounded position, velocity off by a fraction of a grid step.
  const double span = o.sim.cube.timeSpanS();
  const FitParams start{{obj.vxPxPerS + 0.3 / span, obj.vyPxPerS - 0.3 / span},
                        std::round(obj.xRefPx),
                        std::round(obj.yRefPx),
                        std::nan(""),
                        0.0};
  const FitResult r = fitComoving(o.sim.cube, start, o.options);
  ASSERT_TRUE(r.ok()) << r.message;
  SCOPED_TRACE(::testing::Message() << presetName << ": x " << r.params.xc << " vs " << obj.xRefPx << " +- "
                                    << r.sigmaNoiseModel[kXc] << ", SNR " << r.snr << " vs "
                                    << obj.expectedSnr);
  EXPECT_NEAR(r.params.xc, obj.xRefPx, 3 * r.sigmaNoiseModel[kXc]);
  EXPECT_NEAR(r.params.yc, obj.yRefPx, 3 * r.sigmaNoiseModel[kYc]);
  EXPECT_NEAR(r.params.v.vx, obj.vxPxPerS, 3 * r.sigmaNoiseModel[kVx]);
  EXPECT_NEAR(r.params.v.vy, obj.vyPxPerS, 3 * r.sigmaNoiseModel[kVy]);
  EXPECT_NEAR(r.tRefMjd, t.tRefMjd, 1e-9);
  EXPECT_NEAR(r.snr / obj.expectedSnr, 1.0, 0.10);
  const double zp = 2.5 * std::log10(t.zeroPointPhotonsPerS);
  const double mag = astro::magnitude(r.photonsPerFrame / t.exposureS, zp);
  EXPECT_NEAR(mag, obj.magnitude, 0.1);
  // A real object passes the segment checks.
  CancelToken cancel;
  const vet::SegmentReport seg = vet::checkSegments(o.sim.cube, r, o.options, {}, cancel);
  EXPECT_FALSE(seg.flagged()) << (seg.reasons.empty() ? "" : seg.reasons[0]);
}

TEST(FitVsSimulator, Small) {
  expectMatchesTruth("small");
}
TEST(FitVsSimulator, PaperNeo) {
  expectMatchesTruth("paper-neo");
}
TEST(FitVsSimulator, KnownPair) {
  expectMatchesTruth("known-pair");
}

}  // namespace
}  // namespace st::fit
