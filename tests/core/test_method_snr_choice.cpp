// `auto` and the tree's SNR cost (issue 16): the tree is taken only where its loss for the cube's PSF
// (search::treeSnrLoss, measured by test_tree_snr_loss_slow) is <= 3%, and the reason says what it costs.
#include <gtest/gtest.h>

#include <cmath>

#include "st/search/method_choice.hpp"

namespace st::search {
namespace {

MethodEstimate clearlyFasterTree(double fwhm) {
  MethodEstimate e;
  e.exactSeconds = 100.0;
  e.treeSeconds = 5.0;
  e.exactAdditions = 1e12;
  e.treeAdditions = 1e10;
  setPsf(e, fwhm);
  return e;
}

TEST(MethodSnrChoice, TableIsTheMeasuredWorstLossAndRisesBelowOnePointFivePx) {
  EXPECT_NEAR(treeSnrLoss(1.5), 0.030, 1e-12);
  EXPECT_NEAR(treeSnrLoss(2.0), 0.022, 1e-12);
  EXPECT_NEAR(treeSnrLoss(2.25), 0.019, 1e-12);
  EXPECT_NEAR(treeSnrLoss(3.5), 0.010, 1e-12);
  EXPECT_NEAR(treeSnrLoss(6.0), 0.010, 1e-12);
  EXPECT_GT(treeSnrLoss(1.2), kAutoTreeMaxSnrLoss);
  EXPECT_TRUE(std::isnan(treeSnrLoss(0.0)));
}

TEST(MethodSnrChoice, AutoKeepsExactWhereTheTreeLosesMoreThanThreePercent) {
  const MethodChoice narrow = chooseMethod("auto", clearlyFasterTree(1.2), true, "cpu");
  EXPECT_EQ(narrow.method, "exact");
  EXPECT_NE(narrow.reason.find("lose ~3.5% of the SNR at PSF FWHM 1.20 px"), std::string::npos)
      << narrow.reason;
  const MethodChoice wide = chooseMethod("auto", clearlyFasterTree(2.0), true, "cpu");
  EXPECT_EQ(wide.method, "tree");
  EXPECT_NE(wide.reason.find("SNR cost ~2.2% at PSF FWHM 2.00 px"), std::string::npos) << wide.reason;
  // Unknown PSF: the speed rule alone, as before.
  EXPECT_EQ(chooseMethod("auto", clearlyFasterTree(0.0), true, "cpu").method, "tree");
  // Requested: as requested, whatever it costs.
  EXPECT_EQ(chooseMethod("tree", clearlyFasterTree(1.0), true, "cpu").method, "tree");
}

}  // namespace
}  // namespace st::search
