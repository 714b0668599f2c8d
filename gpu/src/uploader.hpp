#pragma once
// What one device keeps between searches (streams, pinned staging buffers: creating them costs ~20-30 ms,
// measured on an H100 2026-11-22), and the upload of frames from pageable host memory through the staging
// buffers (shared by the exact and the tree search).
#include <algorithm>
#include <cstddef>
#include <cstring>
#include <memory>

#include "cuda_check.hpp"
#include "st/common/parallel.hpp"

namespace st::gpu {

/// One pinned staging buffer. 8 MiB pieces were slower (H100, 2026-11-22: the paper's cube uploaded in
/// 117-130 ms instead of 43-51 ms; parallelFor starts its threads for every piece).
inline constexpr std::size_t kStagingBytes = std::size_t{32} << 20;

/// Pins `count` staging buffers (kStagingBytes each) into a process-wide pool, for the next DeviceResources
/// to take: the CUDA backend's creation does it beside the frames' read, so that pre-processing's first
/// upload does not wait for cudaMallocHost (pinned host memory serves every device).
void warmPinnedStaging(int count);
/// A staging buffer from that pool, else a new one.
PinnedBuffer takePinnedStaging();

/// Streams and staging buffers of one device, created with that device current and used by one host thread
/// at a time (the device's search thread). A search that fails drops them (the owner resets the pointer).
struct DeviceResources {
  Stream compute;
  Stream copy;
  Event stagingFree[2];
  int nextStaging = 0;
  /// Staging buffer b (0 or 1), pinned on first use: a search of a resident cube uploads nothing, and
  /// cudaMallocHost of 64 MiB took 29-73 ms (probe on H100 hosts, 2026-11-28; the tree search's whole wall
  /// on the paper's problem is ~0.12 s).
  void* staging(int b) {
    if (!m_staging[b].get()) m_staging[b] = takePinnedStaging();
    return m_staging[b].get();
  }

 private:
  PinnedBuffer m_staging[2];
};

/// The resources in `slot`, made now (with their device current) when it is empty.
inline DeviceResources& ensureResources(std::unique_ptr<DeviceResources>& slot) {
  if (!slot) slot = std::make_unique<DeviceResources>();
  return *slot;
}

/// Copies frames from pageable host memory to the device through the two pinned staging buffers of
/// `resources`, so that the host copy of one piece (on every core) overlaps the DMA of the previous one.
class Uploader {
 public:
  Uploader(DeviceResources& resources, const float* host, std::size_t plane)
      : m_r(resources), m_host(host), m_plane(plane) {}
  /// Enqueues frames [n0, n1) into `dst` on `stream`. Blocks only while a staging buffer is still in flight.
  void upload(float* dst, int n0, int n1, cudaStream_t stream) {
    constexpr std::size_t kPieceFloats = kStagingBytes / sizeof(float);
    const std::size_t total = static_cast<std::size_t>(n1 - n0) * m_plane;
    const float* src = m_host + static_cast<std::size_t>(n0) * m_plane;
    for (std::size_t off = 0; off < total; off += kPieceFloats) {
      const std::size_t piece = std::min(kPieceFloats, total - off);
      const int b = m_r.nextStaging;
      m_r.nextStaging ^= 1;
      m_r.stagingFree[b].sync();
      // Many threads fill the pinned buffer: one thread's memcpy (~10 GB/s) would be slower than the DMA.
      float* dst0 = static_cast<float*>(m_r.staging(b));
      const float* src0 = src + off;
      parallelFor(piece, std::size_t{1} << 19, [&](std::size_t lo, std::size_t hi) {
        std::memcpy(dst0 + lo, src0 + lo, (hi - lo) * sizeof(float));
      });
      ST_CUDA_CHECK(cudaMemcpyAsync(dst + off, dst0, piece * sizeof(float), cudaMemcpyHostToDevice, stream));
      m_r.stagingFree[b].record(stream);
    }
  }

 private:
  DeviceResources& m_r;
  const float* m_host;
  std::size_t m_plane;
};

}  // namespace st::gpu
