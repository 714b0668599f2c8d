#include "st/stack/ipsa.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "st/common/error.hpp"
#include "st/common/parallel.hpp"

namespace st::stack {
namespace {

/// Rows per block: the block's accumulators (kBlockRows x width floats) stay in L1/L2 while every frame's
/// matching rows stream through once.
constexpr int kBlockRows = 16;
constexpr double kMaxShift = 1073741824.0;  // 2^30

int roundShift(double s) {
  return static_cast<int>(std::clamp(std::round(s), -kMaxShift, kMaxShift));
}

void checkCube(const FrameCube& cube, std::size_t offsets) {
  if (cube.empty()) throw InputError("IPSA stack: the cube has no frames");
  if (cube.frameCount() > 65535)
    throw InputError("IPSA stack: " + std::to_string(cube.frameCount()) +
                     " frames exceed the 65535 that the 16-bit N_in count holds");
  if (offsets != cube.frameCount())
    throw InputError("IPSA stack: " + std::to_string(offsets) + " time offsets for " +
                     std::to_string(cube.frameCount()) + " frames");
}

inline void addRow(float* __restrict acc, const float* __restrict src, int n) {
  for (int x = 0; x < n; ++x)
    acc[x] += src[x];
}

}  // namespace

std::vector<IntShift> ipsaShifts(const std::vector<double>& offsetsS, Velocity v,
                                 const std::vector<PixelOffset>& frameOffsets) {
  if (!frameOffsets.empty() && frameOffsets.size() != offsetsS.size()) {
    throw InputError("IPSA shifts: " + std::to_string(frameOffsets.size()) + " frame offsets for " +
                     std::to_string(offsetsS.size()) + " frames");
  }
  std::vector<IntShift> s(offsetsS.size());
  for (std::size_t n = 0; n < offsetsS.size(); ++n) {
    const PixelOffset o = frameOffsets.empty() ? PixelOffset{} : frameOffsets[n];
    s[n] = {roundShift(o.x + v.vx * offsetsS[n]), roundShift(o.y + v.vy * offsetsS[n])};
  }
  return s;
}

void ipsaRows(const FrameCube& cube, const std::vector<IntShift>& shifts, int y0, int y1, float* sum,
              std::uint16_t* nIn) {
  const int w = cube.width(), h = cube.height();
  std::vector<int> diff(static_cast<std::size_t>(w + 1) * kBlockRows);
  for (int yb = y0; yb < y1; yb += kBlockRows) {
    const int ye = std::min(y1, yb + kBlockRows);
    float* acc = sum + std::size_t(yb) * w;
    std::fill(acc, acc + std::size_t(ye - yb) * w, 0.0f);
    std::fill(diff.begin(), diff.end(), 0);
    for (std::size_t n = 0; n < shifts.size(); ++n) {
      const int dx = shifts[n].dx, dy = shifts[n].dy;
      const int xlo = std::max(0, -dx), xhi = std::min(w, w - dx);
      if (xlo >= xhi) continue;
      const int rlo = std::max(yb, -dy), rhi = std::min(ye, h - dy);  // rows whose source row is inside
      const float* frame = cube.frame(n);
      if (n + 2 < shifts.size()) {  // touch the pages of frame n+2's rows: TLB walk and prefetch start early
        const float* nf = cube.frame(n + 2);
        const int r0 = std::clamp(yb + shifts[n + 2].dy, 0, h - 1),
                  r1 = std::clamp(ye + shifts[n + 2].dy, 0, h);
        for (std::size_t off = std::size_t(r0) * w; off < std::size_t(r1) * w; off += 1024)
          __builtin_prefetch(nf + off, 0, 0);
      }
      for (int y = rlo; y < rhi; ++y) {
        addRow(acc + std::size_t(y - yb) * w + xlo, frame + std::size_t(y + dy) * w + xlo + dx, xhi - xlo);
        int* d = diff.data() + std::size_t(y - yb) * (w + 1);
        ++d[xlo];
        --d[xhi];
      }
    }
    for (int y = yb; y < ye; ++y) {
      const int* d = diff.data() + std::size_t(y - yb) * (w + 1);
      std::uint16_t* out = nIn + std::size_t(y) * w;
      int c = 0;
      for (int x = 0; x < w; ++x)
        out[x] = static_cast<std::uint16_t>(c += d[x]);
    }
  }
}

StackResult stackIpsa(const FrameCube& cube, const std::vector<double>& offsetsS, Velocity v) {
  return stackIpsa(cube, offsetsS, v, cube.frameOffsets());
}

StackResult stackIpsa(const FrameCube& cube, const std::vector<double>& offsetsS, Velocity v,
                      const std::vector<PixelOffset>& frameOffsets) {
  checkCube(cube, offsetsS.size());
  StackResult r;
  r.sum = Image(cube.width(), cube.height());
  r.nIn.assign(cube.framePixels(), 0);
  r.velocity = v;
  r.tRefMjd = cube.tRefMjd();
  r.mode = search::StackMode::Ipsa;
  const std::vector<IntShift> shifts = ipsaShifts(offsetsS, v, frameOffsets);
  const std::size_t blocks = (std::size_t(cube.height()) + kBlockRows - 1) / kBlockRows;
  parallelFor(blocks, 2, [&](std::size_t b, std::size_t e) {
    const int y0 = int(b) * kBlockRows, y1 = std::min(cube.height(), int(e) * kBlockRows);
    ipsaRows(cube, shifts, y0, y1, r.sum.data(), r.nIn.data());
  });
  return r;
}

StackResult stackIpsa(const FrameCube& cube, Velocity v) {
  if (cube.empty()) throw InputError("IPSA stack: the cube has no frames");
  return stackIpsa(cube, cube.timeOffsetsS(), v);
}

}  // namespace st::stack
