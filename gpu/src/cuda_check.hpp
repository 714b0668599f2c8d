#pragma once
// Checked CUDA calls and move-only RAII owners of device memory, pinned host memory, streams and events
// (STYLE.md: kbmod's GPUArray, OpenCV's checked launches). C++17: included from .cu and .cpp files.
#include <cuda_runtime.h>

#include <algorithm>
#include <cstddef>
#include <vector>
#include <string>
#include <utility>

#include "st/common/env_flag.hpp"
#include "st/common/error.hpp"

namespace st::gpu {

/// An environment knob (the benchmarks' before/after switches): st::envFlag, read at each call.
inline bool envKnob(const char* name) {
  return envFlag(name);
}

/// Throws st::GpuError naming the call and CUDA's own text when `err` is not cudaSuccess.
inline void check(cudaError_t err, const char* what) {
  if (err != cudaSuccess) {
    throw GpuError(std::string(what) + " failed: " + cudaGetErrorName(err) + " (" + cudaGetErrorString(err) +
                   ")");
  }
}

/// Checks the launch that was just made (cudaGetLastError), naming the kernel.
inline void checkLaunch(const char* kernel) {
  check(cudaGetLastError(), kernel);
}

#define ST_CUDA_CHECK(call) ::st::gpu::check((call), #call)

/// Device memory for `count` objects of T on the current device. Move-only; freed in the destructor.
template <class T>
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  explicit DeviceBuffer(std::size_t count) : m_count(count) {
    if (count > 0) {
      check(cudaMalloc(reinterpret_cast<void**>(&m_ptr), count * sizeof(T)),
            ("cudaMalloc(" + std::to_string(count * sizeof(T)) + " bytes)").c_str());
    }
  }
  DeviceBuffer(DeviceBuffer&& o) noexcept
      : m_ptr(std::exchange(o.m_ptr, nullptr)), m_count(std::exchange(o.m_count, 0)) {}
  DeviceBuffer& operator=(DeviceBuffer&& o) noexcept {
    if (this != &o) {
      release();
      m_ptr = std::exchange(o.m_ptr, nullptr);
      m_count = std::exchange(o.m_count, 0);
    }
    return *this;
  }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  ~DeviceBuffer() { release(); }

  T* get() const noexcept { return m_ptr; }
  std::size_t size() const noexcept { return m_count; }
  std::size_t bytes() const noexcept { return m_count * sizeof(T); }

 private:
  void release() noexcept {
    if (m_ptr) cudaFree(m_ptr);  // errors at teardown cannot be reported; the context may be gone
    m_ptr = nullptr;
    m_count = 0;
  }
  T* m_ptr = nullptr;
  std::size_t m_count = 0;
};

/// `host` copied into a new device buffer (at least one element, so that an empty vector still gives a
/// valid pointer).
template <class T, class Allocator>
DeviceBuffer<T> toDevice(const std::vector<T, Allocator>& host) {
  DeviceBuffer<T> d(std::max<std::size_t>(host.size(), 1));
  if (!host.empty()) {
    ST_CUDA_CHECK(cudaMemcpy(d.get(), host.data(), host.size() * sizeof(T), cudaMemcpyHostToDevice));
    // From pageable memory cudaMemcpy may return before the DMA has reached the device; the kernels that
    // read the buffer run on non-blocking streams, which do not wait for the default stream.
    ST_CUDA_CHECK(cudaStreamSynchronize(nullptr));
  }
  return d;
}

/// Page-locked host memory (staging for asynchronous uploads). Move-only.
class PinnedBuffer {
 public:
  PinnedBuffer() = default;
  explicit PinnedBuffer(std::size_t bytes) : m_bytes(bytes) {
    if (bytes > 0) ST_CUDA_CHECK(cudaMallocHost(&m_ptr, bytes));
  }
  PinnedBuffer(PinnedBuffer&& o) noexcept
      : m_ptr(std::exchange(o.m_ptr, nullptr)), m_bytes(std::exchange(o.m_bytes, 0)) {}
  PinnedBuffer& operator=(PinnedBuffer&& o) noexcept {
    std::swap(m_ptr, o.m_ptr);
    std::swap(m_bytes, o.m_bytes);
    return *this;
  }
  PinnedBuffer(const PinnedBuffer&) = delete;
  PinnedBuffer& operator=(const PinnedBuffer&) = delete;
  ~PinnedBuffer() {
    if (m_ptr) cudaFreeHost(m_ptr);
  }
  void* get() const noexcept { return m_ptr; }
  std::size_t bytes() const noexcept { return m_bytes; }

 private:
  void* m_ptr = nullptr;
  std::size_t m_bytes = 0;
};

/// A non-blocking stream on the current device. Move-only.
class Stream {
 public:
  Stream() { ST_CUDA_CHECK(cudaStreamCreateWithFlags(&m_stream, cudaStreamNonBlocking)); }
  Stream(Stream&& o) noexcept : m_stream(std::exchange(o.m_stream, nullptr)) {}
  Stream& operator=(Stream&&) = delete;
  Stream(const Stream&) = delete;
  Stream& operator=(const Stream&) = delete;
  ~Stream() {
    if (m_stream) cudaStreamDestroy(m_stream);
  }
  cudaStream_t get() const noexcept { return m_stream; }
  void sync() const { ST_CUDA_CHECK(cudaStreamSynchronize(m_stream)); }

 private:
  cudaStream_t m_stream = nullptr;
};

/// An event on the current device (timing enabled when asked). Move-only.
class Event {
 public:
  explicit Event(bool timing = false) {
    ST_CUDA_CHECK(cudaEventCreateWithFlags(&m_event, timing ? cudaEventDefault : cudaEventDisableTiming));
  }
  Event(Event&& o) noexcept : m_event(std::exchange(o.m_event, nullptr)) {}
  Event& operator=(Event&&) = delete;
  Event(const Event&) = delete;
  Event& operator=(const Event&) = delete;
  ~Event() {
    if (m_event) cudaEventDestroy(m_event);
  }
  cudaEvent_t get() const noexcept { return m_event; }
  void record(cudaStream_t s) { ST_CUDA_CHECK(cudaEventRecord(m_event, s)); }
  void sync() const { ST_CUDA_CHECK(cudaEventSynchronize(m_event)); }
  /// Seconds from `a` to `b` (both recorded with timing; synchronises on b).
  static double elapsed(const Event& a, const Event& b) {
    b.sync();
    float ms = 0.0f;
    ST_CUDA_CHECK(cudaEventElapsedTime(&ms, a.m_event, b.m_event));
    return ms * 1e-3;
  }

 private:
  cudaEvent_t m_event = nullptr;
};

}  // namespace st::gpu
