// The GUI's search backend cache (ui/search_backend_cache.hpp): one backend made per kind and reused by
// later searches (the CUDA backend keeps its staging buffers), made again when the kind changes, with the
// message its factory gave; a factory that throws leaves the cache empty so the next search tries again.
#include <gtest/gtest.h>

#include <stdexcept>

#include "search_backend_cache.hpp"
#include "st/search/cpu_backend.hpp"

namespace st::ui {
namespace {

TEST(SearchBackendCache, ReusesTheBackendUntilTheKindChanges) {
  SearchBackendCache cache;
  int made = 0;
  auto make = [&](BackendKind kind, std::string& message) {
    ++made;
    message = kind == BackendKind::Cpu ? "using cpu" : "auto: cpu";
    return search::makeCpuBackend();
  };
  const search::SearchBackend* first = nullptr;
  cache.with(BackendKind::Auto, make, [&](search::SearchBackend& b, const std::string& m) {
    first = &b;
    EXPECT_EQ(m, "auto: cpu");
    return 0;
  });
  cache.with(BackendKind::Auto, make, [&](search::SearchBackend& b, const std::string& m) {
    EXPECT_EQ(&b, first);
    EXPECT_EQ(m, "auto: cpu");
    return 0;
  });
  EXPECT_EQ(made, 1);
  cache.with(BackendKind::Cpu, make, [&](search::SearchBackend&, const std::string& m) {
    EXPECT_EQ(m, "using cpu");
    return 0;
  });
  EXPECT_EQ(made, 2);
}

TEST(SearchBackendCache, AFailedFactoryIsTriedAgain) {
  SearchBackendCache cache;
  int made = 0;
  auto failing = [&](BackendKind, std::string&) -> std::unique_ptr<search::SearchBackend> {
    ++made;
    throw std::runtime_error("CUDA backend not available");
  };
  auto work = [](search::SearchBackend&, const std::string&) { return 0; };
  EXPECT_THROW(cache.with(BackendKind::Gpu, failing, work), std::runtime_error);
  EXPECT_THROW(cache.with(BackendKind::Gpu, failing, work), std::runtime_error);
  EXPECT_EQ(made, 2);
}

}  // namespace
}  // namespace st::ui
