#pragma once
// What one device keeps between searches (streams, pinned staging buffers: creating them costs ~20-30 ms,
// measured on an H100 2026-11-22), and the upload of frames from pageable host memory through the staging
// buffers (shared by the exact and the tree search).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>

#include "cuda_check.hpp"
#include "st/common/parallel.hpp"

#if defined(__x86_64__) || defined(_M_X64)
#include <emmintrin.h>
#endif

namespace st::gpu {

/// memcpy with non-temporal stores (SSE2, every x86-64; memcpy elsewhere and below 4 KiB): the
/// destination's lines are not read before they are written. The staged copies' pieces (up to 2 MiB a task)
/// are below glibc's own non-temporal threshold, so memcpy reads every destination line first: a third more
/// memory traffic beside the stages that run while a cube is uploaded or downloaded (issue 16). The stores
/// are fenced before it returns.
inline void copyStreaming(void* dstv, const void* srcv, std::size_t n) {
#if defined(__x86_64__) || defined(_M_X64)
  if (n >= 4096) {
    char* dst = static_cast<char*>(dstv);
    const char* src = static_cast<const char*>(srcv);
    const std::size_t head = (16 - reinterpret_cast<std::uintptr_t>(dst) % 16) % 16;
    std::memcpy(dst, src, head);
    dst += head, src += head, n -= head;
    std::size_t i = 0;
    for (; i + 64 <= n; i += 64) {
      const __m128i a = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + i));
      const __m128i b = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + i + 16));
      const __m128i c = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + i + 32));
      const __m128i d = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + i + 48));
      _mm_stream_si128(reinterpret_cast<__m128i*>(dst + i), a);
      _mm_stream_si128(reinterpret_cast<__m128i*>(dst + i + 16), b);
      _mm_stream_si128(reinterpret_cast<__m128i*>(dst + i + 32), c);
      _mm_stream_si128(reinterpret_cast<__m128i*>(dst + i + 48), d);
    }
    std::memcpy(dst + i, src + i, n - i);
    _mm_sfence();
    return;
  }
#endif
  std::memcpy(dstv, srcv, n);
}

/// ST_GPU_UPLOAD_MEMCPY=1: the uploads' copies into the staging buffers by memcpy, as before 2026-12-03.
inline bool uploadByMemcpy() {
  static const bool plain = envKnob("ST_GPU_UPLOAD_MEMCPY");
  return plain;
}

/// ST_GPU_DOWNLOAD_MEMCPY=1: the downloads' copies out of the staging buffers by memcpy, as before
/// 2026-12-03.
inline bool downloadByMemcpy() {
  static const bool plain = envKnob("ST_GPU_DOWNLOAD_MEMCPY");
  return plain;
}

/// A staged copy's host side, into a staging buffer (`upload`) or out of one: copyStreaming, or memcpy
/// where the knob of its direction asks for it (uploadByMemcpy, downloadByMemcpy).
enum class StagedDirection { Upload, Download };
inline void copyStaged(void* dst, const void* src, std::size_t n, StagedDirection direction) {
  if (direction == StagedDirection::Upload ? uploadByMemcpy() : downloadByMemcpy())
    std::memcpy(dst, src, n);
  else
    copyStreaming(dst, src, n);
}

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
        copyStaged(dst0 + lo, src0 + lo, (hi - lo) * sizeof(float), StagedDirection::Upload);
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
