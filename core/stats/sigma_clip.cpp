#include "st/stats/sigma_clip.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace st::stats {
namespace {

// Sums over the samples inside [lo, hi], shifted by `shift` so that the one-pass variance does not cancel.
struct Moments {
  std::size_t n = 0;
  double s = 0.0;
  double ss = 0.0;
};

Moments momentsWithin(const float* v, std::size_t n, double lo, double hi, double shift) {
  Moments m;
  for (std::size_t i = 0; i < n; ++i) {
    const double y = v[i];
    if (y < lo || y > hi) continue;
    const double d = y - shift;
    ++m.n;
    m.s += d;
    m.ss += d * d;
  }
  return m;
}

ClipStats clip(const float* v, std::size_t n, double xi, int maxIterations, bool symmetric) {
  ClipStats out;
  if (n == 0) return out;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  double lo = -kInf;
  double hi = kInf;
  const double shift = v[0];
  std::size_t previous = std::numeric_limits<std::size_t>::max();
  for (int it = 1; it <= maxIterations; ++it) {
    const Moments m = momentsWithin(v, n, lo, hi, shift);
    out.iterations = it;
    out.count = m.n;
    if (m.n == 0) break;
    const double meanShifted = m.s / static_cast<double>(m.n);
    out.mean = shift + meanShifted;
    out.sigma =
        m.n > 1 ? std::sqrt(std::max(0.0, (m.ss - m.s * meanShifted) / static_cast<double>(m.n - 1))) : 0.0;
    if (m.n == previous) {
      out.converged = true;
      break;
    }
    previous = m.n;
    hi = out.mean + xi * out.sigma;
    if (symmetric) lo = out.mean - xi * out.sigma;
  }
  return out;
}

}  // namespace

ClipStats sigmaClip(const float* values, std::size_t n, double xi, int maxIterations) {
  return clip(values, n, xi, maxIterations, false);
}

ClipStats sigmaClipSymmetric(const float* values, std::size_t n, double xi, int maxIterations) {
  return clip(values, n, xi, maxIterations, true);
}

}  // namespace st::stats
