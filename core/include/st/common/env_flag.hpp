#pragma once
// The benchmarks' before/after switches read from the environment (ST_NO_HEAP_WARM=1 and the like).
#include <cstdlib>

namespace st {

/// True when the environment variable `name` is set, not empty and does not start with '0'.
inline bool envFlag(const char* name) {
  const char* e = std::getenv(name);
  return e && *e && *e != '0';
}

}  // namespace st
