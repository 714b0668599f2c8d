#pragma once
// The CUDA search backend (exact IPSA on every visible GPU). Only plain types cross this header, so it is
// included from app/ without CUDA headers.
#include <memory>
#include <string>

#include "st/search/types.hpp"

namespace st::gpu {

/// A CUDA backend over every visible device, or nullptr with `whyNot` set (no device, no driver, ...).
std::unique_ptr<search::SearchBackend> makeCudaBackend(std::string& whyNot);

/// One line per visible device ("0: NVIDIA H100 80GB HBM3, 79.1 GiB, sm_90"), or why there is none.
std::string deviceSummary();

}  // namespace st::gpu
