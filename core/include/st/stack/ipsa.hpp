#pragma once
// Integer-Pixel-Shift-Add synthetic tracking (paper §2.1, ARCHITECTURE.md "IPSA"):
//   S(x, y, v) = sum_n F_n(x + round(vx (t_n - t_ref)), y + round(vy (t_n - t_ref)))
// with real frame times (t_n - t_ref from FrameCube::timeOffsetsS()), round = half away from zero
// (std::round), out-of-frame samples contributing nothing and not counted in N_in(x, y).
// Row-wise contiguous adds with precomputed integer shifts and row-range clipping, parallel over row
// blocks; for each pixel the frames are added in order n = 0, 1, ... in float, so the result equals a
// brute-force loop bit for bit. Pure functions of their inputs: safe to call from several threads at once.
#include <cstdint>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/units.hpp"
#include "st/search/types.hpp"

namespace st::stack {

/// A frame's integer shift: frame n is sampled at (x + dx, y + dy).
struct IntShift {
  int dx = 0;
  int dy = 0;
};

/// A 2-D stack with its per-pixel count of contributing frames.
struct StackResult {
  Image sum;                       ///< S(x, y), image units of the frames (sum, not mean)
  std::vector<std::uint16_t> nIn;  ///< frames that contributed to each pixel, row-major like sum
  Velocity velocity;               ///< px/s
  double tRefMjd = 0.0;            ///< reference epoch of the positions (mean of the mid-times)
  search::StackMode mode = search::StackMode::Ipsa;
};

/// round(o_n + v * (t_n - t_ref)) for every frame (std::round; values beyond +-2^30 are clamped, such a frame
/// is out of any image anyway). `frameOffsets` are the frames' registration offsets o_n
/// (FrameCube::frameOffsets(), one per entry of offsetsS); empty = all 0.
std::vector<IntShift> ipsaShifts(const std::vector<double>& offsetsS, Velocity v,
                                 const std::vector<PixelOffset>& frameOffsets = {});

/// The IPSA kernel on rows [y0, y1) only, single-threaded: writes those rows of `sum` and `nIn`, which
/// point to full width x height outputs. For callers that schedule their own threads (search backends).
void ipsaRows(const FrameCube& cube, const std::vector<IntShift>& shifts, int y0, int y1, float* sum,
              std::uint16_t* nIn);

/// The IPSA stack of `cube` at velocity v (px/s), parallel over rows. Throws st::InputError for an empty
/// cube or more than 65535 frames (N_in is 16-bit).
StackResult stackIpsa(const FrameCube& cube, Velocity v);

/// As above with precomputed t_n - t_ref (seconds, one per frame), to avoid recomputing them when
/// scrubbing. Both use the cube's registration offsets (FrameInfo::offsetXPx/offsetYPx). Throws st::InputError when offsetsS.size() != cube.frameCount().
StackResult stackIpsa(const FrameCube& cube, const std::vector<double>& offsetsS, Velocity v);

/// As above with the frames' registration offsets given (one per frame; empty = all 0) instead of the cube's:
/// for frames loaded without them whose registration another cube holds (the GUI's loaded frames and its
/// prepared ones). Throws st::InputError when frameOffsets is neither empty nor one per frame.
StackResult stackIpsa(const FrameCube& cube, const std::vector<double>& offsetsS, Velocity v,
                      const std::vector<PixelOffset>& frameOffsets);

}  // namespace st::stack
