// Photometry and astrometry from co-moving fits (paper §5.1-5.2).
#include <gtest/gtest.h>

#include "test_support.hpp"

#include <cmath>
#include <numbers>

#include "st/astro/astrometry.hpp"
#include "st/astro/photometry.hpp"
#include "st/common/error.hpp"
#include "st/fit/montecarlo.hpp"
#include "st/io/wcs.hpp"

namespace st::astro {
namespace {

TEST(Photometry, ReproducesThePaperMagnitude) {
  // Paper §5.1: ~6300 photons in 30 s, calibrated on a 9.1 mag star giving 8.1e7 photons/s -> 23.1 mag.
  const double zp = zeroPointFromStar(9.1, 8.1e7);
  EXPECT_DOUBLE_EQ(zp, 9.1 + 2.5 * std::log10(8.1e7));
  const double m = magnitude(6300.0 / 30.0, zp);
  EXPECT_NEAR(m, 23.1, 0.05);
  EXPECT_NEAR(m, 23.06566, 1e-5);  // 9.1 + 2.5 log10(8.1e7 / 210)
  EXPECT_DOUBLE_EQ(magnitude(8.1e7, zp), 9.1);
  EXPECT_TRUE(std::isnan(magnitude(0.0, zp)));
}

// Photo-electrons per count: GAIN, divided by an EMCCD's EMGAIN (the simulator's paper-neo header: GAIN 20
// e-/ADU at the output, EMGAIN 200: 0.1 photo-electron per ADU).
TEST(Photometry, PhotoelectronsPerCountFromGainAndEmGain) {
  FitsHeader h;
  EXPECT_DOUBLE_EQ(photoelectronsPerCount(h), 1.0);  // neither: counts are photons
  h.setNumber("EGAIN", 1.5);  // the other spelling, when GAIN is absent
  EXPECT_DOUBLE_EQ(photoelectronsPerCount(h), 1.5);
  h.setNumber("GAIN", 20.0);
  EXPECT_DOUBLE_EQ(photoelectronsPerCount(h), 20.0);
  h.setNumber("EMGAIN", 200.0);
  EXPECT_DOUBLE_EQ(photoelectronsPerCount(h), 0.1);
  h.setNumber("EMGAIN", 1.0);  // no multiplication
  EXPECT_DOUBLE_EQ(photoelectronsPerCount(h), 20.0);
  h.setNumber("GAIN", -3.0);  // not a gain: counts are photons
  EXPECT_DOUBLE_EQ(photoelectronsPerCount(h), 1.0);
  // The EM register's excess noise (variance x2) only with a multiplication.
  EXPECT_DOUBLE_EQ(excessNoiseFactor(h), 1.0);
  h.setNumber("EMGAIN", 200.0);
  EXPECT_DOUBLE_EQ(excessNoiseFactor(h), 2.0);
}

TEST(Photometry, PhotonsFromAmplitudeAndSegmentScatter) {
  const psf::Moffat p{3.3, 4.0};
  EXPECT_DOUBLE_EQ(photonsFromAmplitude(2.0, p, 1.5), 1.5 * 2.0 * std::numbers::pi * 3.3 * 3.3 / 3.0);
  const SegmentScatter s = segmentScatter({200.0, 220.0, 180.0, 200.0});
  EXPECT_DOUBLE_EQ(s.mean, 200.0);
  EXPECT_NEAR(s.sd, std::sqrt(800.0 / 3.0), 1e-12);
  EXPECT_NEAR(s.sigmaMean, std::sqrt(800.0 / 3.0) / 2.0, 1e-12);
  EXPECT_NEAR(s.sigmaMag, 2.5 / std::log(10.0) * s.sigmaMean / 200.0, 1e-12);
  EXPECT_EQ(segmentScatter({1.0}).sd, 0.0);
}

// A gnomonic (TAN) projection, north up and east left: CD = [[-s, 0], [0, s]] deg/px, reference pixel
// (crpix) at (ra0, dec0). Standard formulas (Calabretta & Greisen 2002).
PixelToSky tanProjection(double ra0, double dec0, double scaleArcsec, double crpixX, double crpixY) {
  return [=](double x, double y) {
    const double d = std::numbers::pi / 180.0;
    const double xi = -(x - crpixX) * scaleArcsec / 3600.0 * d;
    const double eta = (y - crpixY) * scaleArcsec / 3600.0 * d;
    const double a0 = ra0 * d, de0 = dec0 * d;
    const double den = std::cos(de0) - eta * std::sin(de0);
    const double ra = a0 + std::atan2(xi, den);
    const double dec = std::atan2(std::sin(de0) + eta * std::cos(de0), std::hypot(xi, den));
    return SkyPoint{std::fmod(ra / d + 360.0, 360.0), dec / d};
  };
}

fit::FitResult fakeFit(double x, double y, Velocity v, double sigmaPos, double sigmaVel) {
  fit::FitResult f;
  f.status = fit::FitStatus::Converged;
  f.params = {v, x, y, 1.0, 0.0};
  f.tRefMjd = 60000.5;
  f.covarianceNoiseModel(fit::kXc, fit::kXc) = f.covarianceNoiseModel(fit::kYc, fit::kYc) =
      sigmaPos * sigmaPos;
  f.covarianceNoiseModel(fit::kVx, fit::kVx) = f.covarianceNoiseModel(fit::kVy, fit::kVy) =
      sigmaVel * sigmaVel;
  return f;
}

TEST(Astrometry, RateAndPositionAngleThroughAWcs) {
  const PixelToSky wcs = tanProjection(150.0, 30.0, 0.3, 100.0, 100.0);
  // Moving north at 1 px/s = 0.3"/s = 18"/min = 7.2 deg/day, PA 0.
  SkyMeasurement m = skyMeasurement(wcs, fakeFit(100.0, 100.0, {0.0, 1.0}, 0.01, 0.001), {}, 0.0);
  EXPECT_NEAR(m.raDeg, 150.0, 1e-12);
  EXPECT_NEAR(m.decDeg, 30.0, 1e-12);
  EXPECT_NEAR(m.rateArcsecPerMin, 18.0, 1e-6);
  EXPECT_NEAR(m.rateDegPerDay, 7.2, 1e-6);
  EXPECT_NEAR(m.positionAngleDeg, 0.0, 1e-6);
  EXPECT_NEAR(m.sigmaRaArcsec, 0.003, 1e-8);
  EXPECT_NEAR(m.sigmaDecArcsec, 0.003, 1e-8);
  EXPECT_NEAR(m.sigmaRateDegPerDay, 0.0072, 1e-8);
  // East is -x here: PA 90. South-west: PA 225.
  m = skyMeasurement(wcs, fakeFit(100.0, 100.0, {-1.0, 0.0}, 0.01, 0.001), {}, 0.0);
  EXPECT_NEAR(m.positionAngleDeg, 90.0, 1e-6);
  m = skyMeasurement(wcs, fakeFit(100.0, 100.0, {1.0, -1.0}, 0.01, 0.001), {}, 0.0);
  EXPECT_NEAR(m.positionAngleDeg, 225.0, 1e-6);
  EXPECT_NEAR(m.rateArcsecPerMin, 18.0 * std::sqrt(2.0), 1e-5);
}

TEST(Astrometry, ThroughAFitsWcsLikeThroughTheSameTanProjection) {
  // A TAN header, CRPIX 1-based = 101 (0-based 100), north up, east left, 0.3"/px.
  FitsHeader h;
  test::setTanWcs(h, 150.0, 30.0, 101.0, 101.0, 0.3);
  std::vector<std::string> warnings;
  const auto wcs = Wcs::fromHeader(h, &warnings);
  ASSERT_NE(wcs, nullptr);
  const fit::FitResult f = fakeFit(130.0, 80.0, {-0.7, 1.3}, 0.02, 0.002);
  const SkyMeasurement a = skyMeasurement(*wcs, f, {}, 0.0);
  const SkyMeasurement b = skyMeasurement(tanProjection(150.0, 30.0, 0.3, 100.0, 100.0), f, {}, 0.0);
  EXPECT_NEAR(a.raDeg, b.raDeg, 1e-9);
  EXPECT_NEAR(a.decDeg, b.decDeg, 1e-9);
  EXPECT_NEAR(a.rateDegPerDay, b.rateDegPerDay, 1e-6 * b.rateDegPerDay);
  EXPECT_NEAR(a.positionAngleDeg, b.positionAngleDeg, 1e-4);
}

TEST(Astrometry, SkyRateIsRemovedAndTheMappingEpochRespected) {
  const PixelToSky wcs = tanProjection(150.0, 30.0, 0.3, 100.0, 100.0);
  // The stars drift at +2 px/s in x; the WCS is of the first frame, 10 s before t_ref. An object that moves
  // with the stars is static on the sky, and its t_ref position maps 20 px back.
  const Velocity sky{2.0, 0.0};
  const SkyMeasurement m = skyMeasurement(wcs, fakeFit(120.0, 100.0, sky, 0.01, 0.001), sky, -10.0);
  EXPECT_NEAR(m.rateDegPerDay, 0.0, 1e-9);
  EXPECT_NEAR(m.raDeg, 150.0, 1e-9);
  EXPECT_NEAR(m.decDeg, 30.0, 1e-9);
}

// skyMotionAt (the CLI report's rate and PA for a fit it maps through --wcs) gives skyMeasurement's rate and
// position angle for the same velocity relative to the stars.
TEST(Astrometry, SkyMotionAtEqualsTheMeasurementsMotion) {
  const PixelToSky wcs = tanProjection(150.0, 60.0, 0.3, 100.0, 100.0);
  const Velocity sky{2.0, -0.5};
  for (const Velocity v : {Velocity{0.0, 1.0}, Velocity{-0.7, 1.3}, Velocity{3.1, -2.2}, sky}) {
    const SkyMeasurement m = skyMeasurement(wcs, fakeFit(130.0, 80.0, v, 0.01, 0.001), sky, 0.0);
    const SkyMotion k = skyMotionAt(wcs, 130.0, 80.0, {v.vx - sky.vx, v.vy - sky.vy});
    EXPECT_DOUBLE_EQ(k.rateDegPerDay, m.rateDegPerDay);
    EXPECT_DOUBLE_EQ(k.rateArcsecPerMin, m.rateArcsecPerMin);
    EXPECT_DOUBLE_EQ(k.positionAngleDeg, m.positionAngleDeg);
  }
  // North at 1 px/s = 7.2 deg/day, PA 0; east (-x) PA 90.
  EXPECT_NEAR(skyMotionAt(wcs, 100.0, 100.0, {0.0, 1.0}).rateDegPerDay, 7.2, 1e-6);
  EXPECT_NEAR(skyMotionAt(wcs, 100.0, 100.0, {-1.0, 0.0}).positionAngleDeg, 90.0, 1e-6);
}

TEST(Astrometry, RateFromAPlateScale) {
  const PlateScaleRate r = rateFromPlateScale(fakeFit(0, 0, {3.0, 4.0}, 0.1, 0.01), {0.0, -1.0}, 0.5);
  // |v - sky| = |(3, 5)| px/s
  EXPECT_NEAR(r.rateArcsecPerMin, std::hypot(3.0, 5.0) * 0.5 * 60.0, 1e-9);
  EXPECT_NEAR(r.rateDegPerDay, pxPerSecToDegPerDay(std::hypot(3.0, 5.0), 0.5), 1e-12);
  EXPECT_NEAR(r.sigmaRateDegPerDay, pxPerSecToDegPerDay(0.01, 0.5), 1e-12);
  EXPECT_THROW((void)rateFromPlateScale(fakeFit(0, 0, {}, 0, 0), {}, 0.0), InputError);
}

TEST(Astrometry, AsteroidRelativeToStarsFittedAtTheSkyRate) {
  const psf::Moffat psf{3.3, 4.0};
  const Velocity sky{0.5, 0.2};
  FrameCube cube = fit::makeEmptyCube(96, 40, 0.06);
  fit::renderMovingSource(cube, psf, {30.4, 30.7, sky, 3000.0});
  fit::renderMovingSource(cube, psf, {70.2, 60.1, sky, 2000.0});
  fit::renderMovingSource(cube, psf, {50.6, 45.3, {4.0, -3.0}, 400.0});
  fit::addNoise(cube, 3.0, true, 17);
  fit::FitOptions o;
  o.psf = psf;
  o.sigmaN = 3.0;
  const auto s1 = fitStar(cube, 30, 31, sky, o);
  const auto s2 = fitStar(cube, 70, 60, sky, o);
  ASSERT_TRUE(s1.ok() && s2.ok());
  EXPECT_EQ(s1.params.v, sky);
  const auto a = fit::fitComoving(cube, {{4.0, -3.0}, 51.0, 45.0, std::nan(""), 0.0}, o);
  ASSERT_TRUE(a.ok()) << a.message;
  const RelativeAstrometry r = relativeToStars(a, {s1, s2});
  ASSERT_EQ(r.starsUsed, 2);
  EXPECT_NEAR(r.perStar[0].dx, 50.6 - 30.4, 4 * r.perStar[0].sigmaX);
  EXPECT_NEAR(r.perStar[0].dy, 45.3 - 30.7, 4 * r.perStar[0].sigmaY);
  EXPECT_NEAR(r.perStar[1].dx, 50.6 - 70.2, 4 * r.perStar[1].sigmaX);
  EXPECT_NEAR(r.x, a.params.xc, 1e-9);
  EXPECT_GT(r.perStar[0].sigmaX, a.sigmaNoiseModel[fit::kXc]);
  fit::FitResult bad = a;
  bad.status = fit::FitStatus::Diverged;
  EXPECT_THROW((void)relativeToStars(bad, {s1}), InputError);
}

}  // namespace
}  // namespace st::astro
