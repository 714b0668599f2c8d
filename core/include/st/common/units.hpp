#pragma once
// Velocity units (ARCHITECTURE.md): internally pixels per second; shown and accepted also as arcsec/min and
// deg/day when a plate scale (arcsec per pixel) is known. Pure arithmetic, tested exactly.
#include <cmath>

namespace st {

/// A velocity in pixels per second: vx along x (columns), vy along y (rows).
struct Velocity {
  double vx = 0.0;
  double vy = 0.0;
  [[nodiscard]] double norm() const noexcept { return std::hypot(vx, vy); }
  friend bool operator==(const Velocity& a, const Velocity& b) noexcept {
    return a.vx == b.vx && a.vy == b.vy;
  }
};

inline constexpr double kSecondsPerDay = 86400.0;
inline constexpr double kArcsecPerDeg = 3600.0;

/// px/s -> arcsec/min for a plate scale in arcsec/px.
constexpr double pxPerSecToArcsecPerMin(double pxPerS, double arcsecPerPx) noexcept {
  return pxPerS * arcsecPerPx * 60.0;
}
constexpr double arcsecPerMinToPxPerSec(double arcsecPerMin, double arcsecPerPx) noexcept {
  return arcsecPerMin / (arcsecPerPx * 60.0);
}
/// px/s -> deg/day: px/s * arcsec/px * 86400 s/day / 3600 arcsec/deg.
constexpr double pxPerSecToDegPerDay(double pxPerS, double arcsecPerPx) noexcept {
  return pxPerS * arcsecPerPx * kSecondsPerDay / kArcsecPerDeg;
}
constexpr double degPerDayToPxPerSec(double degPerDay, double arcsecPerPx) noexcept {
  return degPerDay * kArcsecPerDeg / (kSecondsPerDay * arcsecPerPx);
}

}  // namespace st
