// The CUDA pre-processing accelerator: the device, the global background, the prefetch of the calibrated
// cube, the staged copies and the factory (the stages: cuda_preprocess.hpp).
#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <thread>

#include <system_error>

#include "cuda_preprocess.hpp"
#include "frame_backgrounds.hpp"
#include "global_background_host.hpp"
#include "resident_cube.hpp"
#include "sky_stack_kernels.hpp"
#include "st/common/parallel.hpp"
#include "st/common/sparse_bytes.hpp"

namespace st::gpu {

using namespace preprocess_detail;

void preprocess_detail::download(DeviceResources& r, void* host, const void* dev, std::size_t bytes,
                                 cudaStream_t s, unsigned copyThreads, std::size_t chunkBytes,
                                 const std::atomic<int>* waiters) {
  static const bool keepCap = envKnob("ST_GPU_COPY_CAP_WHILE_WAITED");
  const trace::Scope traced("download");
  r.copy.sync();  // the staging buffers may still feed an upload
  const std::size_t piece = chunkBytes > 0 ? std::min(chunkBytes, kStagingBytes) : kStagingBytes;
  const std::size_t pieces = (bytes + piece - 1) / piece;
  Event ready[2];
  auto enqueue = [&](std::size_t p) {
    const std::size_t off = p * piece, len = std::min(piece, bytes - off);
    ST_CUDA_CHECK(cudaMemcpyAsync(r.staging(static_cast<int>(p & 1)), static_cast<const char*>(dev) + off,
                                  len, cudaMemcpyDeviceToHost, s));
    ready[p & 1].record(s);
  };
  if (pieces > 0) enqueue(0);
  for (std::size_t p = 0; p < pieces; ++p) {
    if (p + 1 < pieces) enqueue(p + 1);
    ready[p & 1].sync();
    const std::size_t off = p * piece, len = std::min(piece, bytes - off);
    char* dst = static_cast<char*>(host) + off;
    const char* src = static_cast<const char*>(r.staging(static_cast<int>(p & 1)));
    // 2 MiB a task for the cubes' pieces; a stack's few MB spread over the threads too.
    const std::size_t chunk =
        std::clamp<std::size_t>(len / workerCount(), std::size_t{1} << 16, std::size_t{1} << 21);
    parallelFor(
        len, chunk,
        [&](std::size_t lo, std::size_t hi) {
          copyStaged(dst + lo, src + lo, hi - lo, StagedDirection::Download);
        },
        !keepCap && waiters && waiters->load(std::memory_order_relaxed) > 0 ? 0u : copyThreads);
  }
}

void preprocess_detail::downloadPieces(DeviceResources& r, const std::vector<DownloadPiece>& pieces,
                                       cudaStream_t s) {
  static const bool oneByOne = [] {
    const char* v = std::getenv("ST_GPU_GATHER_DOWNLOADS");
    return v && std::string(v) == "0";
  }();
  if (oneByOne) {
    for (const DownloadPiece& p : pieces)
      download(r, p.host, p.dev, p.bytes, s);
    return;
  }
  const trace::Scope traced("download (gathered)");
  // Segments of at most kSegment bytes (the host copy's tasks), packed into batches of a staging buffer.
  constexpr std::size_t kSegment = std::size_t{1} << 19;
  struct Segment {
    char* host;
    const char* dev;
    std::size_t bytes, offset;  // offset: in its batch's staging buffer
  };
  std::vector<std::vector<Segment>> batches(1);
  std::size_t used = 0;
  for (const DownloadPiece& p : pieces)
    for (std::size_t off = 0; off < p.bytes; off += kSegment) {
      const std::size_t len = std::min(kSegment, p.bytes - off);
      if (used + len > kStagingBytes) {
        batches.emplace_back();
        used = 0;
      }
      batches.back().push_back(
          {static_cast<char*>(p.host) + off, static_cast<const char*>(p.dev) + off, len, used});
      used += len;
    }
  if (batches.back().empty()) return;  // no bytes at all
  r.copy.sync();                       // the staging buffers may still feed an upload
  Event ready[2];
  auto enqueue = [&](std::size_t b) {
    char* staging = static_cast<char*>(r.staging(static_cast<int>(b & 1)));
    for (const Segment& g : batches[b])
      ST_CUDA_CHECK(cudaMemcpyAsync(staging + g.offset, g.dev, g.bytes, cudaMemcpyDeviceToHost, s));
    ready[b & 1].record(s);
  };
  enqueue(0);
  for (std::size_t b = 0; b < batches.size(); ++b) {
    if (b + 1 < batches.size()) enqueue(b + 1);
    ready[b & 1].sync();
    const char* staging = static_cast<const char*>(r.staging(static_cast<int>(b & 1)));
    const std::vector<Segment>& batch = batches[b];
    parallelFor(batch.size(), 1, [&](std::size_t i0, std::size_t i1) {
      for (std::size_t i = i0; i < i1; ++i)
        copyStaged(batch[i].host, staging + batch[i].offset, batch[i].bytes, StagedDirection::Download);
    });
  }
}

void preprocess_detail::downloadInPlace(DeviceResources& r, void* host, const void* dev, std::size_t bytes,
                                        cudaStream_t s, const std::string& what, const std::string& device) {
  try {
    download(r, host, dev, bytes, s);
  } catch (const GpuError& e) {
    throw Error(what + "'s download from " + device +
                " failed part way, leaving the frames half written: " + e.what());
  }
}

CudaPreprocess::CudaPreprocess(DeviceInfo device)
    : m_device(std::move(device)), m_copies(m_device.ordinal, "cuda: " + m_device.name) {
  try {
    m_warm = std::jthread([this] {
      try {
        ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
        auto r = std::make_unique<DeviceResources>();
        r->staging(0);
        r->staging(1);
        m_res = std::move(r);
      } catch (...) {
        // Left to resources(): the first stage makes them, and reports what fails.
      }
    });
  } catch (const std::system_error&) {
    // No thread: resources() makes them on first use.
  }
}

stats::ClipStats CudaPreprocess::globalBackground(const FrameCube& cube,
                                                  const stats::GlobalBackgroundParams& params) {
  ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
  DeviceResources& r = resources();
  m_note.clear();
  // The frames the frame backgrounds left on the device, when the pipeline vouched they are this cube's.
  if (const float* kept = keptFrames(cube)) {
    const stats::ClipStats out = globalBackgroundOnDevice(
        cube, kept, m_sepMask.size() ? m_sepMask.get() : nullptr, params, r.compute.get());
    m_note = "global background on " + name() + " from the frame backgrounds' frames (no upload)";
    return out;
  }
  finishHostCopies();  // the host frames are read
  return globalBackgroundUploaded(cube, params, r.compute.get());
}

std::optional<std::vector<float>> CudaPreprocess::hotPixelExcess(const FrameCube& cube, double background,
                                                                 const detect::HotPixelParams& params) {
  const float* kept = keptFrames(cube);
  if (!kept) return std::nullopt;
  Stopwatch sw;
  ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
  DeviceResources& r = resources();
  const std::size_t nf = cube.frameCount(), np = cube.framePixels();
  const int blocks = static_cast<int>(
      std::clamp<std::size_t>(static_cast<std::size_t>(params.blocks), 1, std::max<std::size_t>(1, nf)));
  DeviceBuffer<float> excess(np);
  launchHotPixelExcess(kept, m_sepMask.size() ? m_sepMask.get() : nullptr, np, static_cast<int>(nf), blocks,
                       background, excess.get(), r.compute.get());
  std::vector<float> out(np);
  ST_CUDA_CHECK(
      cudaMemcpyAsync(out.data(), excess.get(), np * sizeof(float), cudaMemcpyDeviceToHost, r.compute.get()));
  r.compute.sync();
  m_sepMaskCurrent = false;  // the pipeline masks the hot pixels next (maskedInAllFrames)
  m_sepMaskVouched = false;
  m_note = "hot pixels' block means on " + name() + " from the frame backgrounds' frames: " + ms(sw.lap());
  return out;
}

void CudaPreprocess::framesUnchangedSinceFrameBackgrounds(const FrameCube& cube, bool unchanged) {
  // Benchmark knob: ST_GPU_SEP_NO_REUSE=1 uploads as before (global background, hot pixels on the CPU, the
  // prefetch's pixels).
  const bool reuse = !envKnob("ST_GPU_SEP_NO_REUSE");
  m_sepFramesValid = unchanged && reuse && m_sepFrames.size() > 0 &&
                     m_sepFramesData == cube.pixels().data() && m_sepFrames.size() == cube.pixels().size();
}

void CudaPreprocess::maskedInAllFrames(const FrameCube& cube, const std::vector<std::size_t>& pixels) {
  const std::size_t nf = cube.frameCount(), np = cube.framePixels();
  const bool ours = !stagewise() && m_sepFramesValid && m_sepFrames.size() > 0 &&
                    m_sepFramesData == cube.pixels().data() && m_sepFrames.size() == cube.pixels().size();
  const bool inRange = std::all_of(pixels.begin(), pixels.end(), [np](std::size_t i) { return i < np; });
  // Benchmark knob: ST_GPU_HOT_MASK_UPLOAD=1 uploads the host's mask at the prefetch and scans it for
  // registration, as before 2026-12-03.
  static const bool asBefore = envKnob("ST_GPU_HOT_MASK_UPLOAD");
  try {
    // The kept mask (none before: zeros) with the same pixels set in every frame, on the stream of the
    // stages that read it (the prefetch takes it); the host mask's 393 MB (1500 x 512^2) not scanned and
    // uploaded again (~10 ms the sky rate waited for, H200 2026-12-03).
    if (ours && inRange && !asBefore && (m_sepMask.size() == cube.mask().size() || m_sepMask.size() == 0)) {
      if (cube.mask().empty()) {  // nothing masked on the host (no pixels): nothing to keep
        m_sepMaskCurrent = m_sepMaskVouched = pixels.empty() && m_sepMask.size() == 0;
        return;
      }
      ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
      DeviceResources& r = resources();
      cudaStream_t s = r.compute.get();
      if (m_sepMask.size() == 0) {
        m_sepMask = DeviceBuffer<std::uint8_t>(nf * np);
        ST_CUDA_CHECK(cudaMemsetAsync(m_sepMask.get(), 0, nf * np, s));
      }
      if (!pixels.empty()) {
        const std::vector<std::uint64_t> idx(pixels.begin(), pixels.end());
        const DeviceBuffer<std::uint64_t> idxD = toDevice(idx);
        launchMaskInAllFrames(m_sepMask.get(), idxD.get(), idx.size(), nf, np, s);
        r.compute.sync();  // before the indices are freed
      }
      m_sepMaskCurrent = m_sepMaskVouched = true;
      return;
    }
  } catch (const std::exception&) {
    // Dropped: the prefetch uploads the host's mask.
  }
  m_sepMask = DeviceBuffer<std::uint8_t>();
  m_sepMaskCurrent = m_sepMaskVouched = false;
}

std::shared_ptr<void> CudaPreprocess::prefetch(const FrameCube& cube) {
  // The frame backgrounds' frames: this cube's pixels when the pipeline said so; else freed here, after
  // their download (if it still runs: the upload reads the host frames too).
  const bool takeKept = !stagewise() && m_sepFramesValid && m_sepFramesData == cube.pixels().data() &&
                        m_sepFrames.size() == cube.pixels().size();
  if (!takeKept) finishHostCopies();
  // Taken, they may still feed that download: an exception below waits for it before they are freed.
  const HostCopies::DrainOnError drainOnError(m_copies);
  // Their download may still be writing the host pixels: the prefetch is then known by the cube's shape.
  const bool shapeKeyOnly = takeKept && framesPending(cube);
  DeviceBuffer<float> kept;
  if (takeKept) kept = std::move(m_sepFrames);
  // The mask too, when the kept one is the host's (the hot pixels applied: maskedInAllFrames).
  DeviceBuffer<std::uint8_t> keptMask;
  if (takeKept && m_sepMaskVouched && m_sepMask.size() > 0 && m_sepMask.size() == cube.mask().size())
    keptMask = std::move(m_sepMask);
  dropKeptFrames();
  if (stagewise()) return nullptr;
  if (m_prefetch) m_prefetch->join();
  auto p = std::make_shared<Prefetch>();
  p->data = cube.pixels().data();
  p->size = cube.pixels().size();
  p->maskSize = cube.mask().size();
  p->key = shapeKeyOnly ? cubeShapeKey(cube) : cubeKey(cube);
  p->shapeKeyOnly = shapeKeyOnly;
  p->keptFrames = kept.size() > 0;
  if (p->keptFrames) p->pix = std::move(kept);  // owned by the prefetch from here, not by its thread
  p->keptMask = keptMask.size() > 0;
  if (p->keptMask) p->mask = std::move(keptMask);
  m_note = std::string("prefetch on ") + name() + ": " +
           (p->keptFrames ? "the frame backgrounds' frames" : "the frames uploaded") +
           (p->maskSize == 0 ? ", no mask"
            : p->keptMask    ? ", their mask with the hot pixels set on the device"
                             : ", the mask uploaded");
  const std::uint8_t* maskData = cube.mask().data();
  // A thread of its own, copying on that thread only: the host copies into the pinned staging buffers run
  // beside the CPU stages (static sources, PSF) instead of on every core at the per-pixel background.
  p->thread = std::jthread([this, q = p.get(), maskData]() {
    try {
      Stopwatch sw;
      ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
      DeviceResources& r = ensureResources(m_prefetchRes);
      if (!q->keptFrames) q->pix = DeviceBuffer<float>(q->size);
      const bool uploadTheMask = q->maskSize > 0 && !q->keptMask;
      if (uploadTheMask) q->mask = DeviceBuffer<std::uint8_t>(q->maskSize);
      if (!q->keptFrames)
        stagedUpload(r, q->pix.get(), q->data, q->size * sizeof(float), r.copy.get(), false);
      if (uploadTheMask) uploadMask(r, q->mask.get(), maskData, q->maskSize, r.copy.get(), false);
      r.copy.sync();
      q->seconds = sw.lap();
      q->ok = true;
      q->finished = true;
    } catch (const std::exception&) {
      q->ok = false;  // the per-pixel background uploads the cube itself
      q->finished = true;
    }
  });
  m_prefetch = p;
  // The guard joins the upload's thread when the pipeline lets it go (before its cube is freed).
  // Unused by then (the pipeline stopped before its per-pixel background: cancelled, an error), its device
  // copy is freed rather than held until the next prefetch.
  return std::shared_ptr<void>(static_cast<void*>(p.get()), [this, p](void*) {
    m_copies.drain();  // the frame backgrounds' download may still read the kept frames
    p->join();
    p->ok = false;
    p->pix = DeviceBuffer<float>();
    p->mask = DeviceBuffer<std::uint8_t>();
  });
}

void CudaPreprocess::uploadMask(DeviceResources& r, std::uint8_t* dst, const std::uint8_t* src,
                                std::size_t bytes, cudaStream_t s, bool parallelCopy) {
  // A cube's mask is mostly zeros (hot pixels in every frame, saturated cores): its non-zero bytes, found on
  // every core in a few ms (also for the prefetch, whose copies stay on one thread: the scan is short),
  // scattered into a zeroed buffer. The whole mask through the staging buffers on the prefetch's thread took
  // ~110 ms for 1500 x 512^2 (H100 machine, 2026-11-28), and the sky rate's first block sums then ran on the
  // CPU. Copied whole when over 1/64 of it is set (9 bytes an entry against 1).
  const std::optional<SparseBytes> sparse = sparseBytes({src, bytes}, bytes / 64);
  if (!sparse) {
    stagedUpload(r, dst, src, bytes, s, parallelCopy);
    return;
  }
  ST_CUDA_CHECK(cudaMemsetAsync(dst, 0, bytes, s));
  const DeviceBuffer<std::uint64_t> index = toDevice(sparse->index);
  const DeviceBuffer<std::uint8_t> value = toDevice(sparse->value);
  launchScatter(dst, index.get(), value.get(), sparse->index.size(), s);
  ST_CUDA_CHECK(cudaStreamSynchronize(s));  // done on return, and before the entries are freed
}

void CudaPreprocess::stagedUpload(DeviceResources& r, void* dst, const void* src, std::size_t bytes,
                                  cudaStream_t s, bool parallelCopy) {
  for (std::size_t off = 0; off < bytes; off += kStagingBytes) {
    const std::size_t len = std::min(kStagingBytes, bytes - off);
    const int b = r.nextStaging;
    r.nextStaging ^= 1;
    r.stagingFree[b].sync();
    char* stage = static_cast<char*>(r.staging(b));
    const char* from = static_cast<const char*>(src) + off;
    // The prefetch copies on its own thread only: it runs behind the sky rate, whose threads more copy
    // threads would slow (4 copied the paper's cube and mask in 137 ms instead of one core's 283, H100
    // machine, 2026-11-27 14:41, but one copy thread slows the sky rate least: 15:22 run, pre-processing
    // 2.47-2.50 s). A foreground upload copies on every core.
    const auto copy = [](char* to, const char* in, std::size_t n) {
      copyStaged(to, in, n, StagedDirection::Upload);
    };
    if (parallelCopy)
      parallelFor(len,
                  std::clamp<std::size_t>(len / workerCount(), std::size_t{1} << 16, std::size_t{1} << 21),
                  [&](std::size_t lo, std::size_t hi) { copy(stage + lo, from + lo, hi - lo); });
    else
      copy(stage, from, len);
    ST_CUDA_CHECK(cudaMemcpyAsync(static_cast<char*>(dst) + off, stage, len, cudaMemcpyHostToDevice, s));
    r.stagingFree[b].record(s);
  }
}

std::unique_ptr<CudaPreprocessAccelerator> makeCudaPreprocessAccelerator(std::string& whyNot) {
  try {
    std::vector<DeviceInfo> devices = usableDevices(whyNot);
    if (devices.empty()) return nullptr;
    return std::make_unique<CudaPreprocess>(devices.front());
  } catch (const std::exception& e) {
    whyNot = e.what();
    return nullptr;
  }
}

}  // namespace st::gpu
