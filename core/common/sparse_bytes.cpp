#include "st/common/sparse_bytes.hpp"

#include <atomic>
#include <cstring>

#include "st/common/parallel.hpp"

namespace st {

std::optional<SparseBytes> sparseBytes(std::span<const std::uint8_t> data, std::size_t maxEntries) {
  constexpr std::size_t kPiece = std::size_t{1} << 20;
  constexpr std::size_t kLine = 64;  // bytes tested at once: eight words OR-ed, most lines all zero
  const std::size_t n = data.size();
  const std::size_t pieces = (n + kPiece - 1) / kPiece;
  std::vector<SparseBytes> parts(pieces);
  std::atomic<std::size_t> found{0};
  std::atomic<bool> tooMany{false};
  parallelFor(pieces, 1, [&](std::size_t p0, std::size_t p1) {
    for (std::size_t p = p0; p < p1 && !tooMany.load(std::memory_order_relaxed); ++p) {
      SparseBytes& part = parts[p];
      const std::size_t lo = p * kPiece, hi = std::min(n, lo + kPiece);
      auto take = [&](std::size_t from, std::size_t to) {
        for (std::size_t i = from; i < to; ++i)
          if (data[i] != 0) {
            part.index.push_back(i);
            part.value.push_back(data[i]);
          }
      };
      std::size_t i = lo;
      for (; i + kLine <= hi; i += kLine) {
        std::uint64_t w[kLine / 8];
        std::memcpy(w, data.data() + i, kLine);
        std::uint64_t any = 0;
        for (std::uint64_t v : w)
          any |= v;
        if (any != 0) take(i, i + kLine);
      }
      take(i, hi);
      if (found.fetch_add(part.index.size(), std::memory_order_relaxed) + part.index.size() > maxEntries)
        tooMany.store(true, std::memory_order_relaxed);
    }
  });
  if (tooMany.load()) return std::nullopt;
  SparseBytes out;
  out.index.reserve(found.load());
  out.value.reserve(found.load());
  for (const SparseBytes& part : parts) {
    out.index.insert(out.index.end(), part.index.begin(), part.index.end());
    out.value.insert(out.value.end(), part.value.begin(), part.value.end());
  }
  return out;
}

}  // namespace st
