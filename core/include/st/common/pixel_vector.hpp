#pragma once
// The storage of a cube's pixels: a std::vector<float> whose resize and size constructor leave new floats
// unwritten. A cube's pixels are written before they are read (loaded, simulated, downloaded, copied), and
// std::vector<float>'s zero fill of the paper's 1.5 GB cube took 0.15-0.2 s of one thread at the start of
// the GPU pipeline (perf on an H100 host, issue 16), before the parallel reads could begin. Where zeros are
// wanted they are written on every core (st/common/prefault.hpp, FrameCube's constructor).
#include <cstdint>
#include <memory>
#include <type_traits>
#include <utility>
#include <vector>

namespace st {

/// std::allocator, but value-initialisation default-initialises (no write for trivial types).
template <class T>
struct DefaultInitAllocator : std::allocator<T> {
  using std::allocator<T>::allocator;
  template <class U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

using PixelVector = std::vector<float, DefaultInitAllocator<float>>;
/// A cube's per-pixel mask (FrameCube::mask), for the same reason: its 375 MB zero fill for the paper's cube
/// was 45 ms of one thread.
using MaskVector = std::vector<std::uint8_t, DefaultInitAllocator<std::uint8_t>>;

}  // namespace st
