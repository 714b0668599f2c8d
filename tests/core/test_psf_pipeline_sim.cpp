// The PSF that the pre-processing measures (on the sky-rate stack of the zero-biased frames) against the
// simulator's Moffat (paper \label{MoffatPsf}). Two defects made it ~21% too wide on paper-neo (4.32 px
// against 3.57): the cosmic-ray stage zeroed star cores of drifting stars in thousands of frames (EMCCD
// noise over a Gaussian 7-sigma threshold, and stars compared with their own wings one frame later), and the
// fit ignored the stack's own blur (each frame's trail of 0.98 px plus the rounding of the integer shifts:
// +2%). Tolerance 1.5-2% of the FWHM (the paper-neo preset itself, 0.5%: test_psf_pipeline_sim_slow.cpp), on
// a drifting EMCCD sky (paper-neo's detector) and on a conventional CCD with a different FWHM, beta and a
// diagonal drift.
#include <gtest/gtest.h>

#include "st/pipeline/preprocess.hpp"
#include "st/sim/simulator.hpp"

namespace st::pipeline {
namespace {

Prepared prepare(const sim::SimParams& p, std::uint64_t seed, bool withMasters) {
  NullProgress progress;
  CancelToken cancel;
  sim::SimResult s = sim::simulate(p, seed, progress, cancel);
  PreprocessParams params;
  if (withMasters) {
    params.masters = sim::exactMasters(s);
  }
  params.matchedFilter = false;
  return preprocess(std::move(s.cube), params, progress, cancel);
}

TEST(PsfPipelineSim, PaperNeoDetectorDriftingSky) {
  // paper-neo (EM gain 200, sky drifting 16.4 px/s, FWHM 3.57 px, beta 4) on 192 x 192 px, 150 frames, with
  // three isolated 17th-magnitude stars, hot pixels, cosmic rays and the moving object; no master frames
  // (as the demo).
  sim::SimParams p = sim::preset("paper-neo");
  sim::resize(p, 192, 192, 150);
  p.starCount = 0;
  p.brightStars = 0;
  p.cosmicRaysPerFrame = 0.5;
  p.fixedStars = {{96.3, 40.6, 16.9}, {80.7, 130.2, 17.1}, {120.4, 165.5, 17.3}};
  const Prepared out = prepare(p, 3, false);
  ASSERT_TRUE(out.psfFitted) << (out.notes.empty() ? "" : out.notes.back());
  // Stars that stay in the field are protected from the cosmic-ray stage even before the fix; what remains
  // here is the stack's blur (+1.9% before, -0.95% after): 1.5%.
  EXPECT_NEAR(out.psf.fwhm(), p.psf.fwhm(), 0.015 * p.psf.fwhm());
  EXPECT_NEAR(out.psf.beta, p.psf.beta, 0.1 * p.psf.beta);
}

TEST(PsfPipelineSim, ConventionalCcdDiagonalDriftOtherShape) {
  // A 5 e- CCD at 10 Hz, FWHM 2.6 px with beta 2.5 (broad wings), the sky drifting (9, 5) px/s: trails of
  // (0.81, 0.45) px per 0.09 s exposure.
  sim::SimParams p;
  p.width = 192;
  p.height = 192;
  p.frames = 120;
  p.psf = psf::Moffat::fromFwhm(2.6, 2.5);
  p.skyDriftXPxPerS = 9.0;
  p.skyDriftYPxPerS = 5.0;
  p.starCount = 0;
  p.spikeMagLimit = -10.0;
  p.fixedStars = {{90.2, 60.7, 15.6}, {60.6, 120.3, 15.8}, {130.5, 110.1, 16.0}};
  p.objects.clear();
  const Prepared out = prepare(p, 5, true);  // 2.784 px before the fix (+7%), 2.606 after
  ASSERT_TRUE(out.psfFitted) << (out.notes.empty() ? "" : out.notes.back());
  EXPECT_NEAR(out.psf.fwhm(), p.psf.fwhm(), 0.02 * p.psf.fwhm());
  EXPECT_NEAR(out.psf.beta, p.psf.beta, 0.1 * p.psf.beta);
}

}  // namespace
}  // namespace st::pipeline
