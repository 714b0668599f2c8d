#include "st/astro/astrometry.hpp"

#include <cmath>
#include <numbers>

#include "st/common/error.hpp"

namespace st::astro {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// Position errors: the noise-model covariance when present, else the Hessian one.
const fit::ParamMatrix& bestCovariance(const fit::FitResult& f) {
  return f.covarianceNoiseModel.isZero() ? f.covariance : f.covarianceNoiseModel;
}

double wrap180(double d) {
  while (d > 180.0)
    d -= 360.0;
  while (d <= -180.0)
    d += 360.0;
  return d;
}

}  // namespace

fit::FitResult fitStar(const FrameCube& cube, double x, double y, Velocity skyRate, fit::FitOptions options) {
  options.fixVelocity = true;
  return fit::fitComoving(cube, {skyRate, x, y, std::nan(""), 0.0}, options);
}

RelativeAstrometry relativeToStars(const fit::FitResult& asteroid, const std::vector<fit::FitResult>& stars) {
  if (!asteroid.ok()) {
    throw InputError(std::string("relative astrometry: the asteroid fit did not converge (") +
                     fit::toString(asteroid.status) + ")");
  }
  RelativeAstrometry r;
  const auto& ca = bestCovariance(asteroid);
  double wx = 0, wy = 0, sx = 0, sy = 0;
  for (const auto& s : stars) {
    if (!s.ok()) continue;
    if (std::abs(s.tRefOffsetS - asteroid.tRefOffsetS) > 1e-6) {
      throw InputError("relative astrometry: star and asteroid fits have different reference times");
    }
    const auto& cs = bestCovariance(s);
    RelativeOffset o;
    o.dx = asteroid.params.xc - s.params.xc;
    o.dy = asteroid.params.yc - s.params.yc;
    o.sigmaX = std::sqrt(ca(fit::kXc, fit::kXc) + cs(fit::kXc, fit::kXc));
    o.sigmaY = std::sqrt(ca(fit::kYc, fit::kYc) + cs(fit::kYc, fit::kYc));
    r.perStar.push_back(o);
    if (o.sigmaX > 0 && o.sigmaY > 0) {
      const double ax = 1.0 / (o.sigmaX * o.sigmaX), ay = 1.0 / (o.sigmaY * o.sigmaY);
      wx += ax;
      wy += ay;
      sx += ax * (s.params.xc + o.dx);
      sy += ay * (s.params.yc + o.dy);
    }
  }
  if (r.perStar.empty()) throw InputError("relative astrometry: no star fit converged");
  r.starsUsed = static_cast<int>(r.perStar.size());
  if (wx > 0 && wy > 0) {
    r.x = sx / wx;
    r.y = sy / wy;
    r.sigmaX = 1.0 / std::sqrt(wx);
    r.sigmaY = 1.0 / std::sqrt(wy);
  }
  return r;
}

namespace {

// d(east, north)/d(x, y) of a mapping at (x, y), degrees per pixel (east = dRA cos Dec), by central
// differences over +-0.5 px.
Eigen::Matrix2d skyJacobian(const PixelToSky& pixelToSky, double x, double y, double decDeg) {
  const double cosDec = std::cos(decDeg * kDeg);
  const auto diff = [&](double ddx, double ddy) {
    const SkyPoint a = pixelToSky(x + ddx, y + ddy);
    const SkyPoint b = pixelToSky(x - ddx, y - ddy);
    return Eigen::Vector2d(wrap180(a.raDeg - b.raDeg) * cosDec, a.decDeg - b.decDeg);
  };
  Eigen::Matrix2d j;
  j.col(0) = diff(0.5, 0.0);
  j.col(1) = diff(0.0, 0.5);
  return j;
}

// Rate and position angle of a motion w (deg/s east, north).
SkyMotion motionOf(const Eigen::Vector2d& w) {
  const double rate = w.norm();
  SkyMotion m;
  m.rateDegPerDay = rate * kSecondsPerDay;
  m.rateArcsecPerMin = rate * kArcsecPerDeg * 60.0;
  double pa = std::atan2(w[0], w[1]) / kDeg;
  if (pa < 0) pa += 360.0;
  m.positionAngleDeg = rate > 0 ? pa : 0.0;
  return m;
}

}  // namespace

SkyMotion skyMotionAt(const PixelToSky& pixelToSky, double x, double y, Velocity relativePxPerS) {
  const SkyPoint c = pixelToSky(x, y);
  return motionOf(skyJacobian(pixelToSky, x, y, c.decDeg) *
                  Eigen::Vector2d(relativePxPerS.vx, relativePxPerS.vy));
}

SkyMeasurement skyMeasurement(const PixelToSky& pixelToSky, const fit::FitResult& f, Velocity skyRate,
                              double mappingEpochOffsetS) {
  const double dt = f.tRefOffsetS - mappingEpochOffsetS;
  const double x = f.params.xc - skyRate.vx * dt;
  const double y = f.params.yc - skyRate.vy * dt;
  const SkyPoint c = pixelToSky(x, y);
  SkyMeasurement m;
  m.tRefMjd = f.tRefMjd;
  m.raDeg = c.raDeg;
  m.decDeg = c.decDeg;
  const Eigen::Matrix2d j = skyJacobian(pixelToSky, x, y, c.decDeg);
  const auto& cov = bestCovariance(f);
  Eigen::Matrix2d cp;
  cp << cov(fit::kXc, fit::kXc), cov(fit::kXc, fit::kYc), cov(fit::kYc, fit::kXc), cov(fit::kYc, fit::kYc);
  const Eigen::Matrix2d skyCov = j * cp * j.transpose();
  m.sigmaRaArcsec = std::sqrt(std::max(0.0, skyCov(0, 0))) * kArcsecPerDeg;
  m.sigmaDecArcsec = std::sqrt(std::max(0.0, skyCov(1, 1))) * kArcsecPerDeg;
  const Eigen::Vector2d u(f.params.v.vx - skyRate.vx, f.params.v.vy - skyRate.vy);
  const Eigen::Vector2d w = j * u;  // deg/s east, north
  const double rate = w.norm();
  const SkyMotion motion = motionOf(w);
  m.rateDegPerDay = motion.rateDegPerDay;
  m.rateArcsecPerMin = motion.rateArcsecPerMin;
  m.positionAngleDeg = motion.positionAngleDeg;
  if (rate > 0) {
    Eigen::Matrix2d cv;
    cv << cov(fit::kVx, fit::kVx), cov(fit::kVx, fit::kVy), cov(fit::kVy, fit::kVx), cov(fit::kVy, fit::kVy);
    const Eigen::Vector2d g = j.transpose() * w / rate;
    m.sigmaRateDegPerDay = std::sqrt(std::max(0.0, g.dot(cv * g))) * kSecondsPerDay;
  }
  return m;
}

PlateScaleRate rateFromPlateScale(const fit::FitResult& f, Velocity skyRate, double arcsecPerPx) {
  if (!(arcsecPerPx > 0.0)) {
    throw InputError("plate scale must be positive, got " + std::to_string(arcsecPerPx) + " arcsec/px");
  }
  const Velocity u{f.params.v.vx - skyRate.vx, f.params.v.vy - skyRate.vy};
  const double speed = u.norm();
  PlateScaleRate r;
  r.rateDegPerDay = pxPerSecToDegPerDay(speed, arcsecPerPx);
  r.rateArcsecPerMin = pxPerSecToArcsecPerMin(speed, arcsecPerPx);
  if (speed > 0) {
    const auto& cov = bestCovariance(f);
    const double gx = u.vx / speed, gy = u.vy / speed;
    const double var = gx * gx * cov(fit::kVx, fit::kVx) + 2 * gx * gy * cov(fit::kVx, fit::kVy) +
                       gy * gy * cov(fit::kVy, fit::kVy);
    r.sigmaRateDegPerDay = pxPerSecToDegPerDay(std::sqrt(std::max(0.0, var)), arcsecPerPx);
  }
  return r;
}

}  // namespace st::astro
