// The static-source check (issue 18 §6): a source as bright at the sky rate as at its own velocity is flagged.
#include <gtest/gtest.h>

#include "st/vet/artifacts.hpp"

namespace st::vet {
namespace {

TEST(StaticSourceFlag, TheLowellStreakIsFlaggedAMoverIsNot) {
  // The walkthrough's streak: 14.6 at the sky rate against 15.3 at its own velocity.
  const ArtifactFlag streak = staticSourceFlag(15.3, 14.6);
  EXPECT_EQ(streak.kind, ArtifactKind::StaticSource);
  EXPECT_TRUE(streak.triggered);
  EXPECT_NEAR(streak.value, 14.6 / 15.3, 1e-12);
  EXPECT_NE(streak.evidence.find("14.6"), std::string::npos) << streak.evidence;
  // A mover smeared out at the sky rate.
  EXPECT_FALSE(staticSourceFlag(15.3, 2.1).triggered);
  EXPECT_FALSE(staticSourceFlag(10.0, 7.9).triggered);
  EXPECT_TRUE(staticSourceFlag(10.0, 8.0).triggered);
  EXPECT_FALSE(staticSourceFlag(0.0, 3.0).triggered);
  EXPECT_STREQ(toString(ArtifactKind::StaticSource), "static_source");
}

}  // namespace
}  // namespace st::vet
