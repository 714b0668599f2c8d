// st_gpu_copy_probe: what bounds the paper's cube's host copies (issue 16). Pre-processing ends with 3 GB of
// device -> host copies (the zero-biased and the filtered cube) through the pinned staging buffers at
// ~30-40 GB/s; this measures, for one cube of `frames` x `size`^2 floats:
//   - the DMA alone into a pinned staging buffer (32 MiB pieces), and into a whole pinned cube;
//   - preprocess_detail::download (the pipeline's path: DMA into staging, copied out on every core);
//   - the host's own copy rate, pageable to pageable on every core;
//   - cudaHostRegister of a pageable (touched) cube, the DMA straight into it, and cudaHostUnregister;
//   - the upload (Uploader) alone, and while another thread registers a cube (does pinning stall it?).
// Usage: st_gpu_copy_probe [frames=1500] [size=512] [rounds=3]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "cuda_check.hpp"
#include "cuda_preprocess.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "uploader.hpp"

namespace {

using Clock = std::chrono::steady_clock;

double seconds(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

/// `cudaHostRegister` of [data, data + bytes) until destroyed (unregistered also when an error unwinds).
class Registered {
 public:
  Registered(void* data, std::size_t bytes) : m_data(data) {
    ST_CUDA_CHECK(cudaHostRegister(data, bytes, cudaHostRegisterDefault));
  }
  ~Registered() {
    if (m_data) cudaHostUnregister(m_data);
  }
  Registered(const Registered&) = delete;
  Registered& operator=(const Registered&) = delete;
  /// Unregisters now (timed by the caller).
  void release() { ST_CUDA_CHECK(cudaHostUnregister(std::exchange(m_data, nullptr))); }

 private:
  void* m_data;
};

void report(const char* what, double s, std::size_t bytes) {
  std::printf("  %-58s %8.1f ms  %6.1f GB/s\n", what, 1e3 * s, static_cast<double>(bytes) / s / 1e9);
}

/// Seconds of the device -> host DMA of `bytes` from `dev` in staging-buffer-sized pieces on `s` (to its
/// sync), piece p (at byte offset off) into dest(p, off).
template <class Dest>
double dmaInPieces(const float* dev, std::size_t bytes, cudaStream_t s, Dest dest) {
  const auto t0 = Clock::now();
  for (std::size_t off = 0, p = 0; off < bytes; off += st::gpu::kStagingBytes, ++p)
    ST_CUDA_CHECK(cudaMemcpyAsync(dest(p, off), reinterpret_cast<const char*>(dev) + off,
                                  std::min(st::gpu::kStagingBytes, bytes - off), cudaMemcpyDeviceToHost, s));
  ST_CUDA_CHECK(cudaStreamSynchronize(s));
  return seconds(t0);
}

/// Touches every page of `v` on every core (the pipeline's cubes are written before they are copied into).
void touch(std::vector<float>& v) {
  st::parallelFor(v.size(), std::size_t{1} << 20,
                  [&](std::size_t lo, std::size_t hi) { std::fill(v.data() + lo, v.data() + hi, 1.0f); });
}

int run(int argc, char** argv) {
  const int frames = argc > 1 ? std::atoi(argv[1]) : 1500;
  const int size = argc > 2 ? std::atoi(argv[2]) : 512;
  const int rounds = argc > 3 ? std::atoi(argv[3]) : 3;
  if (frames <= 0 || size <= 0 || rounds <= 0) {
    std::fprintf(stderr, "usage: st_gpu_copy_probe [frames > 0] [size > 0] [rounds > 0]\n");
    return 2;
  }
  const std::size_t count = static_cast<std::size_t>(frames) * size * size, bytes = count * sizeof(float);
  std::printf("cube %d x %d^2: %.2f GB; %u host threads\n", frames, size, bytes / 1e9, st::workerCount());
  ST_CUDA_CHECK(cudaSetDevice(0));
  st::gpu::DeviceBuffer<float> dev(count);
  ST_CUDA_CHECK(cudaMemset(dev.get(), 0, bytes));
  st::gpu::DeviceResources r;
  r.staging(0);  // pinned here, not inside the first round's timings
  r.staging(1);
  cudaStream_t s = r.copy.get();
  std::vector<float> host(count), other(count);
  touch(host);
  touch(other);
  for (int round = 1; round <= rounds; ++round) {
    std::printf("round %d\n", round);
    {
      // DMA alone, 32 MiB pieces into the two staging buffers, alternating, no host copy.
      const double t = dmaInPieces(dev.get(), bytes, s, [&](std::size_t p, std::size_t) {
        return r.staging(static_cast<int>(p & 1));
      });
      report("DMA alone into the staging buffers (32 MiB pieces)", t, bytes);
    }
    {
      const auto t0 = Clock::now();
      st::gpu::preprocess_detail::download(r, host.data(), dev.get(), bytes, s);
      report("download(): staging, copied out on every core", seconds(t0), bytes);
    }
    {
      const auto t0 = Clock::now();
      st::parallelFor(count, std::size_t{1} << 19, [&](std::size_t lo, std::size_t hi) {
        std::memcpy(other.data() + lo, host.data() + lo, (hi - lo) * sizeof(float));
      });
      report("host memcpy, pageable to pageable, every core", seconds(t0), bytes);
    }
    {
      const auto t0 = Clock::now();
      Registered pinned(host.data(), bytes);
      report("cudaHostRegister of the touched cube", seconds(t0), bytes);
      const auto t1 = Clock::now();
      ST_CUDA_CHECK(cudaMemcpyAsync(host.data(), dev.get(), bytes, cudaMemcpyDeviceToHost, s));
      ST_CUDA_CHECK(cudaStreamSynchronize(s));
      report("DMA straight into the registered cube (one copy)", seconds(t1), bytes);
      const double t2 = dmaInPieces(dev.get(), bytes, s, [&](std::size_t, std::size_t off) {
        return static_cast<void*>(reinterpret_cast<char*>(host.data()) + off);
      });
      report("DMA straight into the registered cube (32 MiB pieces)", t2, bytes);
      const auto t3 = Clock::now();
      ST_CUDA_CHECK(cudaMemcpyAsync(dev.get(), host.data(), bytes, cudaMemcpyHostToDevice, s));
      ST_CUDA_CHECK(cudaStreamSynchronize(s));
      report("upload straight from the registered cube", seconds(t3), bytes);
      const auto t4 = Clock::now();
      pinned.release();
      report("cudaHostUnregister", seconds(t4), bytes);
    }
    {
      const auto t0 = Clock::now();
      st::gpu::Uploader up(r, other.data(), static_cast<std::size_t>(size) * size);
      up.upload(dev.get(), 0, frames, s);
      ST_CUDA_CHECK(cudaStreamSynchronize(s));
      report("Uploader alone (staging, filled on every core)", seconds(t0), bytes);
    }
    {
      // The same upload while another thread registers the other cube (unregistered after the join; the
      // thread's failure, if any, rethrown here).
      double registerS = 0.0;
      std::optional<Registered> pinned;
      std::exception_ptr pinError;
      const auto t0 = Clock::now();
      std::jthread pinner([&] {
        try {
          const auto p0 = Clock::now();
          pinned.emplace(host.data(), bytes);
          registerS = seconds(p0);
        } catch (...) {
          pinError = std::current_exception();
        }
      });
      st::gpu::Uploader up(r, other.data(), static_cast<std::size_t>(size) * size);
      up.upload(dev.get(), 0, frames, s);
      ST_CUDA_CHECK(cudaStreamSynchronize(s));
      const double uploadS = seconds(t0);
      pinner.join();
      if (pinError) std::rethrow_exception(pinError);
      report("Uploader while another thread registers a cube", uploadS, bytes);
      report("  ... that cudaHostRegister", registerS, bytes);
    }
  }
  {
    const auto t0 = Clock::now();
    st::gpu::PinnedBuffer whole(bytes);  // cudaMallocHost (freed by cudaFreeHost also on an error)
    void* pinned = whole.get();
    report("cudaMallocHost of a cube", seconds(t0), bytes);
    const auto t1 = Clock::now();
    ST_CUDA_CHECK(cudaMemcpyAsync(pinned, dev.get(), bytes, cudaMemcpyDeviceToHost, s));
    ST_CUDA_CHECK(cudaStreamSynchronize(s));
    report("DMA into it (first touch)", seconds(t1), bytes);
    const auto t2 = Clock::now();
    ST_CUDA_CHECK(cudaMemcpyAsync(pinned, dev.get(), bytes, cudaMemcpyDeviceToHost, s));
    ST_CUDA_CHECK(cudaStreamSynchronize(s));
    report("DMA into it (again)", seconds(t2), bytes);
    const auto t3 = Clock::now();
    whole = st::gpu::PinnedBuffer();
    report("cudaFreeHost", seconds(t3), bytes);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "st_gpu_copy_probe: %s\n", e.what());
    return 1;
  }
}
