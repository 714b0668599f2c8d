#pragma once
// A search backend that falls back to another when the first fails for a device reason (issue 5: with no
// GPU, no driver or out of device memory the app searches on the CPU with a clear message, never a crash
// and never a silent wrong answer).
#include <memory>
#include <string>

#include "st/search/types.hpp"

namespace st::search {

/// Runs `primary`; when it throws st::GpuError (out of device memory, a failed launch, a lost device), runs
/// the same call on `fallback` and says so in SearchResult::warnings. After one failure every later call
/// goes to `fallback` (the device is not trusted again). st::Cancelled and st::InputError pass through.
/// name() and supportsMethod() are those of the backend that will run the next call.
std::unique_ptr<SearchBackend> makeFallbackBackend(std::unique_ptr<SearchBackend> primary,
                                                   std::unique_ptr<SearchBackend> fallback);

}  // namespace st::search
