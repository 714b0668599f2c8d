// The staged device -> host download (gpu/src: preprocess_detail::download): every byte arrives, whatever the
// size and the DMA chunk (pieces around one and two staging buffers, odd remainders); white-box, on the
// device. Skips when no CUDA device is usable.
#include <gtest/gtest.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "cuda_check.hpp"
#include "cuda_preprocess.hpp"
#include "uploader.hpp"

namespace st::gpu {
namespace {

TEST(StagedDownload, EveryByteArrivesWhateverTheSizeAndChunk) {
  int devices = 0;
  if (cudaGetDeviceCount(&devices) != cudaSuccess || devices == 0) GTEST_SKIP() << "no usable CUDA device";
  ST_CUDA_CHECK(cudaSetDevice(0));
  constexpr std::size_t kMiB = std::size_t{1} << 20;
  const std::size_t most = 4 * kStagingBytes + 12345;
  std::vector<std::uint8_t> source(most);
  std::mt19937_64 rng(7);
  for (std::size_t i = 0; i + 8 <= most; i += 8) {
    const std::uint64_t v = rng();
    std::memcpy(source.data() + i, &v, 8);
  }
  DeviceBuffer<std::uint8_t> dev(most);
  ST_CUDA_CHECK(cudaMemcpy(dev.get(), source.data(), most, cudaMemcpyHostToDevice));
  DeviceResources r;
  // Sizes around one and two staging buffers, an odd remainder, and the whole; chunks of a staging buffer
  // (0), of the frame backgrounds' kind, and odd.
  const std::size_t sizes[] = {1,
                               4095,
                               kStagingBytes,
                               2 * kStagingBytes,
                               2 * kStagingBytes + 1,
                               2 * kStagingBytes + kStagingBytes / 4 + 3,
                               3 * kStagingBytes - 1,
                               4 * kStagingBytes,
                               most};
  const std::size_t chunks[] = {0, 8 * kMiB, 3 * kMiB + 7};
  for (const std::size_t chunk : chunks)
    for (const std::size_t bytes : sizes) {
      SCOPED_TRACE("bytes " + std::to_string(bytes) + ", chunk " + std::to_string(chunk));
      // From an offset into the device buffer, so that the pieces' sources are not all aligned.
      const std::size_t from = most - bytes;
      std::vector<std::uint8_t> host(bytes + 2, 0xA5);
      preprocess_detail::download(r, host.data() + 1, dev.get() + from, bytes, r.copy.get(), 0, chunk);
      EXPECT_EQ(std::memcmp(host.data() + 1, source.data() + from, bytes), 0);
      EXPECT_EQ(host.front(), 0xA5);  // nothing written outside
      EXPECT_EQ(host.back(), 0xA5);
    }
}

}  // namespace
}  // namespace st::gpu
