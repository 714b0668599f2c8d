#pragma once
// The GPU pre-processing tests' wait for a prefetch: the device answers "none" until the prefetch's upload is
// done (the CPU makes the result meanwhile), so a test asks again until then.
#include <chrono>
#include <thread>

namespace st::test {

/// Asks until the prefetch's upload is done (none before: the CPU makes it meanwhile).
template <class F>
auto whenUploaded(F f) -> decltype(f()) {
  decltype(f()) r;
  for (int tries = 0; tries < 1000 && !r; ++tries) {
    r = f();
    if (!r) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return r;
}

}  // namespace st::test
