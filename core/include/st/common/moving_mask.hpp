#pragma once
// A set of pixels given at the reference epoch t_ref and carried along with the sky motion: in frame n the
// pixel (x, y) is covered when (x - sx_n, y - sy_n) is set at t_ref, with (sx_n, sy_n) =
// (round(ox_n + vx (t_n - t_ref)), round(oy_n + vy (t_n - t_ref))) (o_n the frame's registration offset),
// the integer shift of ARCHITECTURE.md's IPSA
// convention. Its canvas spans every reference position that some frame sees, so stars that drift into or
// out of the field are covered too. Used to exclude static sources from the background and to zero them.
// Pure geometry on the frames' times and offsets, so it lives in common: the background statistics (stats)
// and the static-source detection (detect) both use it (st/detect/moving_mask.hpp keeps the old name).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/units.hpp"

namespace st {

class MovingMask {
 public:
  MovingMask() = default;
  /// A mask for frames of width x height at the given offsets t_n - t_ref (seconds) and sky rate (px/s).
  /// `frameOffsets` are the frames' registration offsets o_n (FrameCube::frameOffsets(); empty = all 0): the
  /// shift of frame n is then round(o_n + rate (t_n - t_ref)), the search's own (ARCHITECTURE.md).
  MovingMask(int width, int height, const std::vector<double>& timeOffsetsS, Velocity rate,
             const std::vector<PixelOffset>& frameOffsets = {});
  /// The mask of `cube`'s frames (size, times and registration offsets) at sky rate `rate`.
  MovingMask(const FrameCube& cube, Velocity rate);

  [[nodiscard]] bool empty() const noexcept { return m_canvas.empty(); }
  /// Canvas geometry: canvas pixel (i, j) is the reference position (x0 + i, y0 + j).
  [[nodiscard]] int x0() const noexcept { return m_x0; }
  [[nodiscard]] int y0() const noexcept { return m_y0; }
  [[nodiscard]] int canvasWidth() const noexcept { return m_cw; }
  [[nodiscard]] int canvasHeight() const noexcept { return m_ch; }
  [[nodiscard]] int shiftX(std::size_t n) const { return m_sx[n]; }
  [[nodiscard]] int shiftY(std::size_t n) const { return m_sy[n]; }
  [[nodiscard]] std::size_t frameCount() const noexcept { return m_sx.size(); }
  [[nodiscard]] Velocity rate() const noexcept { return m_rate; }

  /// Sets the reference position (x, y); positions off the canvas are ignored.
  void set(int x, int y);
  /// Sets every reference position `other` has set (the union; positions off this canvas are ignored).
  void add(const MovingMask& other);
  [[nodiscard]] bool isSetAtRef(int x, int y) const;
  /// True when pixel (x, y) of frame n is covered.
  [[nodiscard]] bool covers(std::size_t n, int x, int y) const {
    return isSetAtRef(x - m_sx[n], y - m_sy[n]);
  }
  /// covers(n, x, y) for the whole row y of frame n, x = 0 .. width - 1, into out[x] (1 = covered): one
  /// canvas row read, for loops over every pixel of a frame.
  void coveredRow(std::size_t n, int y, std::uint8_t* out) const;
  /// Grows every set region by a disc of `radius` pixels.
  void dilate(int radius);
  /// Number of set reference positions.
  [[nodiscard]] std::size_t count() const;
  /// Raw canvas (canvasWidth x canvasHeight, row-major, 1 = set).
  [[nodiscard]] const std::vector<std::uint8_t>& canvas() const noexcept { return m_canvas; }

 private:
  int m_w = 0, m_h = 0;
  int m_x0 = 0, m_y0 = 0, m_cw = 0, m_ch = 0;
  Velocity m_rate;
  std::vector<int> m_sx, m_sy;
  std::vector<std::uint8_t> m_canvas;
};

}  // namespace st
