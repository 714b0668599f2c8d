#pragma once
// The non-zero bytes of a large, mostly zero byte array (a cube's mask: hot pixels, saturated cores), found
// on every core: what a device needs to rebuild the array in a zeroed buffer, at a small fraction of its
// size (issue 16: the prefetch's mask of 1500 x 512^2, 0.4 GB, took ~110 ms through the staging buffers).
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace st {

/// data[index[k]] == value[k] != 0 for every k, indices ascending; every other byte is 0.
struct SparseBytes {
  std::vector<std::uint64_t> index;
  std::vector<std::uint8_t> value;
};

/// The non-zero bytes of `data`; none when there are more than `maxEntries` (the array is then better copied
/// whole). Scans on parallelFor's threads.
[[nodiscard]] std::optional<SparseBytes> sparseBytes(std::span<const std::uint8_t> data,
                                                     std::size_t maxEntries);

}  // namespace st
