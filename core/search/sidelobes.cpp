#include "st/search/sidelobes.hpp"

#include <algorithm>
#include <cmath>

#include "st/psf/moffat.hpp"
#include "st/search/ipsa.hpp"

namespace st::search {
namespace {

/// The matched filter's response to a point source at distance r, K(r) / K(0): the autocorrelation of a
/// Moffat PSF (beta 4, the paper's §3.3 value) of the filter's FWHM, tabulated in r on a 1/8 FWHM grid
/// out to where it falls below 1e-3 (at most 8 FWHM), linear in between.
class FilterResponse {
 public:
  explicit FilterResponse(double fwhmPx) : m_step(fwhmPx / 8.0) {
    // Integration on the table's own grid, +-4 FWHM, so that a shift by r_k is a shift by k samples.
    const psf::Moffat p{psf::Moffat::radiusForFwhm(fwhmPx, 4.0), 4.0};
    const int n = 32;
    const int kMax = 64;  // 8 FWHM
    const int cols = 2 * n + 1 + kMax;
    std::vector<double> grid(static_cast<std::size_t>(cols) * (2 * n + 1));
    for (int j = 0; j <= 2 * n; ++j)
      for (int i = 0; i < cols; ++i)
        grid[static_cast<std::size_t>(j) * cols + i] = p((i - n) * m_step, (j - n) * m_step);
    const auto autocorrelation = [&](int k) {
      double sum = 0.0;
      for (int j = 0; j <= 2 * n; ++j)
        for (int i = 0; i <= 2 * n; ++i)
          sum +=
              grid[static_cast<std::size_t>(j) * cols + i] * grid[static_cast<std::size_t>(j) * cols + i + k];
      return sum;
    };
    const double zero = autocorrelation(0);
    for (int k = 0; k <= kMax; ++k) {
      m_table.push_back(autocorrelation(k) / zero);
      if (m_table.back() < 1e-3) break;
    }
  }
  /// Distance beyond which the response is below 1e-3.
  [[nodiscard]] double reach() const { return m_step * static_cast<double>(m_table.size() - 1); }
  [[nodiscard]] double operator()(double dx, double dy) const {
    const double u = std::sqrt(dx * dx + dy * dy) / m_step;
    const auto i = static_cast<std::size_t>(u);
    if (i + 1 >= m_table.size()) return 0.0;
    const double f = u - static_cast<double>(i);
    return m_table[i] * (1.0 - f) + m_table[i + 1] * f;
  }

 private:
  double m_step;
  std::vector<double> m_table;
};

/// Sum over the frames of `cell`'s samples inside the image of K(sample - source position at dt_n), and
/// the number of those frames.
std::pair<double, int> responseSum(const Candidate& source, const Candidate& cell,
                                   const std::vector<double>& dtS, int width, int height,
                                   const FilterResponse& k, const std::vector<PixelOffset>& offsets) {
  double sum = 0.0;
  int inside = 0;
  for (std::size_t n = 0; n < dtS.size(); ++n) {
    const double dt = dtS[n];
    const PixelOffset o = offsets.empty() ? PixelOffset{} : offsets[n];
    const int sx = cell.x + ipsaShift(cell.v.vx, dt, o.x);
    const int sy = cell.y + ipsaShift(cell.v.vy, dt, o.y);
    if (sx < 0 || sy < 0 || sx >= width || sy >= height) continue;
    ++inside;
    sum += k(sx - (source.x + o.x + source.v.vx * dt), sy - (source.y + o.y + source.v.vy * dt));
  }
  return {sum, inside};
}

double sidelobeSnr(const Candidate& source, const Candidate& cell, const std::vector<double>& dtS, int width,
                   int height, const FilterResponse& k, const std::vector<PixelOffset>& offsets) {
  const auto [own, nSource] = responseSum(source, source, dtS, width, height, k, offsets);
  const auto [cross, nCell] = responseSum(source, cell, dtS, width, height, k, offsets);
  if (nSource == 0 || nCell == 0 || !(own > 0.0)) return 0.0;
  return source.snr * std::sqrt(static_cast<double>(nSource) / nCell) * cross / own;
}

}  // namespace

double closestApproach(const Candidate& a, const Candidate& b, double t0, double t1) {
  const double px = a.x - b.x, py = a.y - b.y;
  const double vx = a.v.vx - b.v.vx, vy = a.v.vy - b.v.vy;
  const double v2 = vx * vx + vy * vy;
  const double t = v2 > 0.0 ? std::clamp(-(px * vx + py * vy) / v2, t0, t1) : 0.0;
  return std::hypot(px + vx * t, py + vy * t);
}

double sidelobeSnr(const Candidate& source, const Candidate& cell, const std::vector<double>& dtS, int width,
                   int height, double psfFwhmPx) {
  return sidelobeSnr(source, cell, dtS, width, height, FilterResponse(psfFwhmPx), {});
}

std::size_t mergeSidelobes(std::vector<Candidate>& candidates, const std::vector<double>& dtS, int width,
                           int height, double psfFwhmPx, double snrThreshold,
                           const std::vector<PixelOffset>& offsets) {
  if (candidates.size() < 2 || dtS.empty() || !(psfFwhmPx > 0.0)) return 0;
  const auto [t0, t1] = std::minmax_element(dtS.begin(), dtS.end());
  const FilterResponse k(psfFwhmPx);
  // Beyond this distance K < 1e-3: no contribution worth the sums (+1 px for the rounding of shifts).
  const double reach = k.reach() + 1.0;
  std::vector<bool> merged(candidates.size(), false);
  std::size_t count = 0;
  for (std::size_t i = 1; i < candidates.size(); ++i) {
    double best = 0.0;
    std::size_t into = 0;
    for (std::size_t j = 0; j < i; ++j) {
      if (merged[j] || closestApproach(candidates[i], candidates[j], *t0, *t1) > reach) continue;
      const double snr = sidelobeSnr(candidates[j], candidates[i], dtS, width, height, k, offsets);
      if (snr > best) best = snr, into = j;
    }
    if (best > 0.0 && candidates[i].snr - best < snrThreshold) {
      merged[i] = true;
      candidates[into].clusterCells += candidates[i].clusterCells;
      ++count;
    }
  }
  std::size_t out = 0;
  for (std::size_t i = 0; i < candidates.size(); ++i)
    if (!merged[i]) candidates[out++] = candidates[i];
  candidates.resize(out);
  return count;
}

}  // namespace st::search
