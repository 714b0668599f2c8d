// Known objects (issue 8): the CSV list, linear propagation on the sky, and the match within a radius.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "st/common/error.hpp"
#include "st/vet/known_objects.hpp"
#include "test_support.hpp"

namespace st::vet {
namespace {

void write(const std::filesystem::path& p, const std::string& text) {
  std::ofstream(p) << text;
}

TEST(KnownObjects, SeparationOracle) {
  EXPECT_NEAR(separationArcsec(10.0, 20.0, 10.0, 20.0 + 1.0 / 3600.0), 1.0, 1e-9);
  // Along RA at Dec 60: 2 arcsec of RA is 1 arcsec on the sky (small-angle, to 1e-9).
  EXPECT_NEAR(separationArcsec(10.0, 60.0, 10.0 + 2.0 / 3600.0, 60.0), 1.0, 1e-6);
  EXPECT_NEAR(separationArcsec(359.9999, 0.0, 0.0001, 0.0), 0.72, 1e-6);  // across RA = 0
  EXPECT_NEAR(separationArcsec(0.0, 90.0, 123.0, 90.0), 0.0, 1e-9);
}

TEST(KnownObjects, ReadsBothRateUnitsAndPropagatesLinearly) {
  test::TempDir dir;
  write(dir / "a.csv",
        "# two known NEAs\n"
        "name,ra_deg,dec_deg,ra_rate_arcsec_min,dec_rate_arcsec_min,epoch_mjd,extra\n"
        "\"2024 AB, test\",10.0,20.0,60.0,-30.0,60000.0,x\n"
        "\n"
        "(433) Eros,359.99,-5.0,-12.0,0.0,60000.5,y\n");
  write(dir / "b.csv",
        "Epoch_MJD,Name,RA_deg,Dec_deg,RA_rate_deg_day,Dec_rate_deg_day\n60000.0,x,10.0,20.0,24.0,-12.0\n");
  const auto a = readKnownObjects((dir / "a.csv").string());
  ASSERT_EQ(a.size(), 2u);
  EXPECT_EQ(a[0].name, "2024 AB, test");
  const auto b = readKnownObjects((dir / "b.csv").string());
  ASSERT_EQ(b.size(), 1u);
  EXPECT_DOUBLE_EQ(b[0].raRateArcsecPerMin, 60.0);  // 24 deg/day = 60 "/min
  EXPECT_DOUBLE_EQ(b[0].decRateArcsecPerMin, -30.0);
  // One hour later: Dec -0.5 deg; RA +1 deg on the sky = 1/cos(19.75 deg) deg of RA.
  const SkyPosition p = propagate(a[0], 60000.0 + 1.0 / 24.0);
  EXPECT_NEAR(p.decDeg, 19.5, 1e-9);  // MJD 6e4 + 1/24 carries ~1e-12 day of rounding
  EXPECT_NEAR(p.raDeg, 10.0 + 1.0 / std::cos(19.75 * M_PI / 180.0), 1e-9);
  // The on-sky distance moved is the rate times the time, to 0.05" over 1.1 deg (linear motion on a sphere).
  EXPECT_NEAR(separationArcsec(10.0, 20.0, p.raDeg, p.decDeg), 3600.0 * std::hypot(1.0, 0.5), 0.05 * 1.1);
  // RA wraps into [0, 360).
  const SkyPosition w = propagate(a[1], 60000.5 + 1.0 / 24.0);
  EXPECT_GE(w.raDeg, 0.0);
  EXPECT_NEAR(w.raDeg, 359.99 - 0.2 / std::cos(5.0 * M_PI / 180.0), 1e-9);
}

TEST(KnownObjects, MatchWithinTheRadiusOnly) {
  const std::vector<KnownObject> list = {{"far", 11.0, 20.0, 0.0, 0.0, 60000.0},
                                         {"mover", 10.0, 20.0, 60.0, 0.0, 60000.0}};
  const double mjd = 60000.0 + 10.0 / 1440.0;  // 10 min: the mover went 600" east
  const SkyPosition at = propagate(list[1], mjd);
  const auto m = matchKnownObject(list, at.raDeg, at.decDeg + 3.0 / 3600.0, mjd, 5.0);
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(m->object->name, "mover");
  EXPECT_NEAR(m->separationArcsec, 3.0, 1e-6);
  // At its epoch position (where it no longer is) nothing matches.
  EXPECT_FALSE(matchKnownObject(list, 10.0, 20.0, mjd, 5.0).has_value());
  const ArtifactFlag on = knownObjectFlag(list, at.raDeg, at.decDeg + 3.0 / 3600.0, mjd, 5.0);
  EXPECT_TRUE(on.triggered) << on.evidence;
  EXPECT_NE(on.evidence.find("mover"), std::string::npos);
  const ArtifactFlag off = knownObjectFlag(list, at.raDeg, at.decDeg + 30.0 / 3600.0, mjd, 5.0);
  EXPECT_FALSE(off.triggered);
  EXPECT_NEAR(off.value, 30.0, 1e-6);
  EXPECT_FALSE(knownObjectFlag({}, 0.0, 0.0, mjd, 5.0).triggered);
}

TEST(KnownObjects, ErrorsNameTheFileLineAndColumn) {
  test::TempDir dir;
  write(dir / "norate.csv", "name,ra_deg,dec_deg,epoch_mjd\nx,1,2,3\n");
  write(dir / "bad.csv",
        "name,ra_deg,dec_deg,epoch_mjd,ra_rate_arcsec_min,dec_rate_arcsec_min\nx,1,2,3,4,5\ny,1,abc,3,4,5\n");
  write(dir / "dec.csv",
        "name,ra_deg,dec_deg,epoch_mjd,ra_rate_arcsec_min,dec_rate_arcsec_min\nx,1,95,3,4,5\n");
  auto message = [](const std::filesystem::path& p) {
    try {
      (void)readKnownObjects(p.string());
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message(dir / "norate.csv").find("rates"), std::string::npos);
  const std::string bad = message(dir / "bad.csv");
  EXPECT_NE(bad.find("line 3"), std::string::npos) << bad;
  EXPECT_NE(bad.find("dec_deg"), std::string::npos) << bad;
  EXPECT_NE(message(dir / "dec.csv").find("beyond"), std::string::npos);
  EXPECT_NE(message(dir / "missing.csv").find("cannot read"), std::string::npos);
}

}  // namespace
}  // namespace st::vet
