// PSF measured on the simulator's frames (issue 3 item 5): the Moffat R and beta the simulator drew with are
// recovered within 2% from the zero-velocity stack of calibrated frames, with the star chosen automatically.
#include <gtest/gtest.h>

#include <cmath>

#include "st/psf/psf_star.hpp"
#include "st/sim/simulator.hpp"
#include "st/stack/ipsa.hpp"

namespace st::psf {
namespace {

TEST(PsfOnSimulator, RecoversRadiusAndBetaWithin2Percent) {
  sim::SimParams p;
  p.width = 96;
  p.height = 96;
  p.frames = 24;
  p.starCount = 0;
  p.spikeMagLimit = -10.0;  // no diffraction spikes: they are not part of the Moffat model
  p.cosmicRaysPerFrame = 0.0;
  p.hotPixels = 0;
  // One isolated star (~2e5 photons per 0.09 s frame, peak ~1.8e4 e-, below the 6e4 e- full well) and a
  // fainter one that the automatic choice must pass over.
  p.fixedStars = {{47.3, 50.6, 13.0}, {20.0, 22.0, 16.5}};
  NullProgress progress;
  CancelToken cancel;
  sim::SimResult s = sim::simulate(p, 7, progress, cancel);
  // Calibrate with the simulator's exact bias and flat, subtract nothing else (the fit has a background).
  FrameCube& cube = s.cube;
  for (std::size_t n = 0; n < cube.frameCount(); ++n) {
    float* f = cube.frame(n);
    for (std::size_t i = 0; i < cube.framePixels(); ++i)
      f[i] = (f[i] - s.biasFrame.pixels[i]) / s.flatFrame.pixels[i];
  }
  const Image still = stack::stackIpsa(cube, Velocity{0.0, 0.0}).sum;
  const PsfMeasurement m = measurePsf(still, {});
  EXPECT_NEAR(m.star.x, 47.3, 1.0);
  EXPECT_NEAR(m.star.y, 50.6, 1.0);
  ASSERT_TRUE(m.fit.converged());
  EXPECT_NEAR(m.fit.model.radius, p.psf.radius, 0.02 * p.psf.radius);
  EXPECT_NEAR(m.fit.model.beta, p.psf.beta, 0.02 * p.psf.beta);
  EXPECT_NEAR(m.fit.fwhm(), p.psf.fwhm(), 0.01 * p.psf.fwhm());
  EXPECT_NEAR(m.fit.x0, 47.3, 0.02);
  EXPECT_NEAR(m.fit.y0, 50.6, 0.02);
}

}  // namespace
}  // namespace st::psf
