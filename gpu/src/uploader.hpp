#pragma once
// Upload of frames from pageable host memory through pinned staging buffers (shared by the exact and the
// tree search).
#include <algorithm>
#include <cstddef>
#include <cstring>

#include "cuda_check.hpp"
#include "st/common/parallel.hpp"

namespace st::gpu {

inline constexpr std::size_t kStagingBytes = std::size_t{32} << 20;  // one pinned staging buffer

/// Copies frames from pageable host memory to the device through two pinned staging buffers, so that the
/// host copy of one piece (on every core) overlaps the DMA of the previous one.
class Uploader {
 public:
  Uploader(const float* host, std::size_t plane, std::size_t totalFloats)
      : m_host(host), m_plane(plane), m_pieceFloats(std::min(totalFloats, kStagingBytes / sizeof(float))) {
    for (auto& b : m_pinned)
      b = PinnedBuffer(m_pieceFloats * sizeof(float));
  }
  /// Enqueues frames [n0, n1) into `dst` on `stream`. Blocks only while a staging buffer is still in flight.
  void upload(float* dst, int n0, int n1, cudaStream_t stream) {
    const std::size_t total = static_cast<std::size_t>(n1 - n0) * m_plane;
    const float* src = m_host + static_cast<std::size_t>(n0) * m_plane;
    for (std::size_t off = 0; off < total; off += m_pieceFloats) {
      const std::size_t piece = std::min(m_pieceFloats, total - off);
      const int b = m_next;
      m_next ^= 1;
      m_free[b].sync();
      // Many threads fill the pinned buffer: one thread's memcpy (~10 GB/s) would be slower than the DMA.
      float* dst0 = static_cast<float*>(m_pinned[b].get());
      const float* src0 = src + off;
      parallelFor(piece, std::size_t{1} << 19, [&](std::size_t lo, std::size_t hi) {
        std::memcpy(dst0 + lo, src0 + lo, (hi - lo) * sizeof(float));
      });
      ST_CUDA_CHECK(cudaMemcpyAsync(dst + off, m_pinned[b].get(), piece * sizeof(float),
                                    cudaMemcpyHostToDevice, stream));
      m_free[b].record(stream);
    }
  }

 private:
  const float* m_host;
  std::size_t m_plane;
  std::size_t m_pieceFloats;
  PinnedBuffer m_pinned[2];
  Event m_free[2];
  int m_next = 0;
};

}  // namespace st::gpu
