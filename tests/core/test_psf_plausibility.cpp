// A radial-profile fit that converged numerically but does not describe a star near the click is rejected
// (issue 18 §6: "(-1578.8, 7430.4): FWHM 0.05 px, beta 50.00" was reported "converged").
#include <gtest/gtest.h>

#include "st/psf/moffat_fit.hpp"

namespace st::psf {
namespace {

MoffatFit fitAt(double x, double y, double radius, double beta) {
  MoffatFit f;
  f.x0 = x;
  f.y0 = y;
  f.model.radius = radius;
  f.model.beta = beta;
  f.convergence = FitConvergence::RelativeReduction;
  return f;
}

TEST(PsfPlausibility, TheIssuesAbsurdFitIsRejectedAndAStarIsNot) {
  // A star 0.4 px from the click, FWHM ~3 px, beta 3: plausible.
  const MoffatFit star = fitAt(100.4, 50.0, 2.0, 3.0);
  ASSERT_NEAR(star.fwhm(), 2.04, 0.01);
  EXPECT_EQ(implausibleFit(star, 100.0, 50.0, 512, 512), "");
  // The walkthrough's fit: centre far outside a 512 x 512 frame, FWHM 0.05 px, beta 50.
  const MoffatFit absurd = fitAt(-1578.8, 7430.4, 0.19, 50.0);
  EXPECT_LT(absurd.fwhm(), 0.06);
  EXPECT_NE(implausibleFit(absurd, 200.0, 300.0, 512, 512).find("outside the image"), std::string::npos);
  // Each rule on its own.
  EXPECT_NE(implausibleFit(fitAt(120.0, 50.0, 2.0, 3.0), 100.0, 50.0, 512, 512).find("from the point clicked"),
            std::string::npos);
  EXPECT_NE(implausibleFit(fitAt(100.0, 50.0, 0.1, 3.0), 100.0, 50.0, 512, 512).find("narrower than a pixel"),
            std::string::npos);
  EXPECT_NE(implausibleFit(fitAt(100.0, 50.0, 200.0, 3.0), 100.0, 50.0, 512, 512).find("wider"),
            std::string::npos);
  EXPECT_NE(implausibleFit(fitAt(100.0, 50.0, 6.0, 50.0), 100.0, 50.0, 512, 512).find("beta"),
            std::string::npos);
  // A wide star is allowed to sit further from the click (2 FWHM).
  EXPECT_EQ(implausibleFit(fitAt(108.0, 50.0, 5.0, 3.0), 100.0, 50.0, 512, 512), "");
}

}  // namespace
}  // namespace st::psf
