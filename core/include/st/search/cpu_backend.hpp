#pragma once
// The CPU search backend: exact IPSA over the whole velocity grid, on all cores. The reference every other
// backend is checked against.
#include <memory>

#include "st/search/types.hpp"

namespace st::search {

std::unique_ptr<SearchBackend> makeCpuBackend();

}  // namespace st::search
