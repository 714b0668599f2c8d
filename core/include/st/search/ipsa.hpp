#pragma once
// The IPSA statistic of ARCHITECTURE.md, in the exact form every backend must reproduce:
//   S(x, y, v) = sum_n F_n(x + round(ox_n + vx dt_n), y + round(oy_n + vy dt_n)),  dt_n = t_n - t_ref in
//   seconds, o_n the frame's registration offset (FrameInfo::offsetXPx/offsetYPx, 0 unless registered),
// out-of-frame samples excluded and not counted (N_in), SNR = S / (sigma_F sqrt(N_in)).
// round() is round-half-away-from-zero of the double product (std::lround; CUDA llround on doubles).
// This header also gives the brute-force reference (one cell, a plain loop) the tests compare against.
#include <cmath>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/units.hpp"

namespace st::search {

/// Integer pixel shift of a source moving at vPxS (px/s) after dtS seconds: round(v * dt), halves away
/// from zero, exactly std::lround of the double product (written out because lround is a slow libm call
/// and the search computes many shifts; p - trunc(p) is exact for |p| < 2^52). Products beyond +-2^30 px
/// are clamped there (such a sample is outside any frame anyway).
inline int ipsaShift(double vPxS, double dtS) noexcept {
  constexpr double kLimit = 1073741824.0;  // 2^30
  double p = vPxS * dtS;
  if (!(p < kLimit)) p = kLimit;  // also catches NaN
  if (p < -kLimit) p = -kLimit;
  const auto t = static_cast<long long>(p);  // toward zero
  const double f = p - static_cast<double>(t);
  return static_cast<int>(f >= 0.5 ? t + 1 : (f <= -0.5 ? t - 1 : t));
}

/// The registered shift of ARCHITECTURE.md: round(o + v dt) for a frame with registration offset `offsetPx`
/// (FrameInfo::offsetXPx or offsetYPx), the same rounding as above (o = 0 gives ipsaShift(v, dt) exactly).
inline int ipsaShift(double vPxS, double dtS, double offsetPx) noexcept {
  return ipsaShift(1.0, offsetPx + vPxS * dtS);
}

/// One cell of the statistic, computed the slow, obvious way.
struct IpsaCell {
  double sum = 0.0;  ///< S, accumulated in double
  int nIn = 0;       ///< frames whose shifted sample lies inside the frame
};

/// Brute-force IPSA at pixel (x, y) (0-based, at t_ref) and velocity v (px/s). `dt` are t_n - t_ref in
/// seconds (FrameCube::timeOffsetsS()); the frames' registration offsets are taken from the cube. For tests
/// and spot checks only: O(frames).
IpsaCell ipsaReference(const FrameCube& cube, const std::vector<double>& dt, int x, int y, Velocity v);

/// N_in along one row for shifts that need not be monotone in time (registered frames): out[c] = number of
/// frames k with 0 <= y + sy[k] < height and 0 <= x0 + c + sx[k] < width, c in [0, count). O(frames + count);
/// `diff` is scratch (resized here).
void countFramesInRow(const int* sx, const int* sy, int frames, int y, int width, int height, int x0, int count,
                      std::vector<int>& diff, int* out);

}  // namespace st::search
