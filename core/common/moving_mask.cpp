#include "st/common/moving_mask.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "st/common/parallel.hpp"

namespace st {

MovingMask::MovingMask(const FrameCube& cube, Velocity rate)
    : MovingMask(cube.width(), cube.height(), cube.timeOffsetsS(), rate, cube.frameOffsets()) {}

MovingMask::MovingMask(int width, int height, const std::vector<double>& timeOffsetsS, Velocity rate,
                       const std::vector<PixelOffset>& frameOffsets)
    : m_w(width), m_h(height), m_rate(rate) {
  m_sx.reserve(timeOffsetsS.size());
  m_sy.reserve(timeOffsetsS.size());
  for (std::size_t n = 0; n < timeOffsetsS.size(); ++n) {
    const double dt = timeOffsetsS[n];
    const PixelOffset o = n < frameOffsets.size() ? frameOffsets[n] : PixelOffset{};
    m_sx.push_back(static_cast<int>(std::lround(o.x + rate.vx * dt)));
    m_sy.push_back(static_cast<int>(std::lround(o.y + rate.vy * dt)));
  }
  const auto [minX, maxX] = std::minmax_element(m_sx.begin(), m_sx.end());
  const auto [minY, maxY] = std::minmax_element(m_sy.begin(), m_sy.end());
  const int sxLo = m_sx.empty() ? 0 : *minX, sxHi = m_sx.empty() ? 0 : *maxX;
  const int syLo = m_sy.empty() ? 0 : *minY, syHi = m_sy.empty() ? 0 : *maxY;
  // Reference position X = x - sx ranges over [-sxHi, w - 1 - sxLo].
  m_x0 = -sxHi;
  m_y0 = -syHi;
  m_cw = width + (sxHi - sxLo);
  m_ch = height + (syHi - syLo);
  m_canvas.assign(static_cast<std::size_t>(m_cw) * static_cast<std::size_t>(m_ch), 0);
}

void MovingMask::set(int x, int y) {
  const int i = x - m_x0, j = y - m_y0;
  if (i < 0 || j < 0 || i >= m_cw || j >= m_ch) return;
  m_canvas[static_cast<std::size_t>(j) * m_cw + i] = 1;
}

void MovingMask::add(const MovingMask& other) {
  const auto& c = other.m_canvas;
  for (std::size_t i = 0; i < c.size(); ++i)
    if (c[i])
      set(other.m_x0 + static_cast<int>(i % static_cast<std::size_t>(other.m_cw)),
          other.m_y0 + static_cast<int>(i / static_cast<std::size_t>(other.m_cw)));
}

bool MovingMask::isSetAtRef(int x, int y) const {
  const int i = x - m_x0, j = y - m_y0;
  if (i < 0 || j < 0 || i >= m_cw || j >= m_ch) return false;
  return m_canvas[static_cast<std::size_t>(j) * m_cw + i] != 0;
}

void MovingMask::coveredRow(std::size_t n, int y, std::uint8_t* out) const {
  std::fill(out, out + m_w, std::uint8_t{0});
  const int j = y - m_sy[n] - m_y0;
  if (m_canvas.empty() || j < 0 || j >= m_ch) return;
  const std::uint8_t* row = m_canvas.data() + static_cast<std::size_t>(j) * m_cw;
  const int shift = m_sx[n] + m_x0;  // frame column x is canvas column x - shift
  const int xb = std::max(0, shift), xe = std::min(m_w, m_cw + shift);
  for (int x = xb; x < xe; ++x)
    out[x] = row[x - shift] != 0;
}

void MovingMask::dilate(int radius) {
  if (radius <= 0 || m_canvas.empty()) return;
  std::vector<std::uint8_t> out(m_canvas);
  const int r2 = radius * radius;
  // By bands of output rows on every core: a band takes the discs of the set pixels within `radius` rows of
  // it and writes only its own rows (the same pixels set as one pass over the canvas).
  constexpr int kBandRows = 16;
  const std::size_t bands = static_cast<std::size_t>((m_ch + kBandRows - 1) / kBandRows);
  parallelFor(bands, 1, [&](std::size_t b0, std::size_t b1) {
    for (std::size_t b = b0; b < b1; ++b) {
      const int y0 = static_cast<int>(b) * kBandRows, y1 = std::min(m_ch, y0 + kBandRows);
      for (int j = std::max(0, y0 - radius); j < std::min(m_ch, y1 + radius); ++j) {
        const std::uint8_t* row = m_canvas.data() + static_cast<std::size_t>(j) * m_cw;
        for (int i = 0; i < m_cw; ++i) {
          if (!row[i]) continue;
          for (int jj = std::max(y0, j - radius); jj < std::min(y1, j + radius + 1); ++jj) {
            const int dj = jj - j;
            std::uint8_t* o = out.data() + static_cast<std::size_t>(jj) * m_cw;
            for (int di = -radius; di <= radius; ++di) {
              const int ii = i + di;
              if (ii < 0 || ii >= m_cw || di * di + dj * dj > r2) continue;
              o[ii] = 1;
            }
          }
        }
      }
    }
  });
  m_canvas.swap(out);
}

std::size_t MovingMask::count() const {
  return static_cast<std::size_t>(std::count(m_canvas.begin(), m_canvas.end(), std::uint8_t{1}));
}

}  // namespace st
