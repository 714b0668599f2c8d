#pragma once
// FNV-1a, 64 bits: the project's one hash of bytes (batch digests, the device's tree-plan key, the
// fingerprints of `bench preprocess`). Not cryptographic.
#include <cstddef>
#include <cstdint>

namespace st {

inline constexpr std::uint64_t kFnv1aBasis = 1469598103934665603ull;

/// `h` with the `bytes` bytes at `data` mixed in, one at a time (start from kFnv1aBasis).
[[nodiscard]] inline std::uint64_t fnv1a(const void* data, std::size_t bytes,
                                         std::uint64_t h = kFnv1aBasis) noexcept {
  constexpr std::uint64_t kPrime = 1099511628211ull;
  const auto* b = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < bytes; ++i)
    h = (h ^ b[i]) * kPrime;
  return h;
}

}  // namespace st
