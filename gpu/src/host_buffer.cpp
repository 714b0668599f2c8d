#include "host_buffer.hpp"

#include "st/common/prefault.hpp"

namespace st::gpu {

std::vector<float> prefaultedFloats(std::size_t n) { return prefaultedZeros(n, 0.0f); }

}  // namespace st::gpu
