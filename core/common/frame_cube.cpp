#include "st/common/frame_cube.hpp"

#include <algorithm>
#include <numeric>
#include <string>

#include "st/common/error.hpp"
#include "st/common/prefault.hpp"
#include "st/common/units.hpp"

namespace st {

namespace {

void checkFrameSize(int width, int height) {
  if (width <= 0 || height <= 0) {
    throw InputError("frame size must be positive, got " + std::to_string(width) + "x" +
                     std::to_string(height));
  }
}

}  // namespace

FrameCube::FrameCube(int width, int height, std::size_t frames) : m_width(width), m_height(height) {
  checkFrameSize(width, height);
  // A large cube's pages are faulted in and zeroed on every core (st/common/prefault.hpp): the loader's
  // 1.5 GB cube took ~0.4 s of single-threaded page faults before the parallel reads (issue 16).
  m_pixels = prefaultedZeros(framePixels() * frames, 0.0f);
  m_info.resize(frames);
}

FrameCube::FrameCube(int width, int height, std::size_t frames, Unwritten)
    : m_width(width), m_height(height) {
  checkFrameSize(width, height);
  m_pixels = prefaultedPixels(framePixels() * frames);
  m_info.resize(frames);
}

FrameCube FrameCube::forOverwrite(int width, int height, std::size_t frames) {
  return FrameCube(width, height, frames, Unwritten{});
}

Image FrameCube::frameImage(std::size_t n) const {
  Image img(m_width, m_height);
  std::copy_n(frame(n), framePixels(), img.pixels.begin());
  return img;
}

double FrameCube::tRefMjd() const {
  if (m_info.empty()) throw InputError("the frame cube has no frames");
  // Sum offsets from the first epoch so MJDs of ~6e4 lose no precision.
  const double t0 = m_info.front().mjdMid;
  double sum = 0.0;
  for (const auto& f : m_info)
    sum += f.mjdMid - t0;
  return t0 + sum / static_cast<double>(m_info.size());
}

std::vector<double> FrameCube::timeOffsetsS() const {
  const double tRef = tRefMjd();
  std::vector<double> out(m_info.size());
  std::transform(m_info.begin(), m_info.end(), out.begin(),
                 [tRef](const FrameInfo& f) { return (f.mjdMid - tRef) * kSecondsPerDay; });
  return out;
}

std::vector<PixelOffset> FrameCube::frameOffsets() const {
  std::vector<PixelOffset> out(m_info.size());
  for (std::size_t n = 0; n < m_info.size(); ++n)
    out[n] = {m_info[n].offsetXPx, m_info[n].offsetYPx};
  return out;
}

bool FrameCube::hasFrameOffsets() const noexcept {
  return std::any_of(m_info.begin(), m_info.end(),
                     [](const FrameInfo& f) { return f.offsetXPx != 0.0 || f.offsetYPx != 0.0; });
}

double FrameCube::timeSpanS() const {
  if (m_info.empty()) return 0.0;
  const auto [lo, hi] = std::minmax_element(m_info.begin(), m_info.end(),
                                            [](const auto& a, const auto& b) { return a.mjdMid < b.mjdMid; });
  return (hi->mjdMid - lo->mjdMid) * kSecondsPerDay;
}

}  // namespace st
