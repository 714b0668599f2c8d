#include "st/search/fallback_backend.hpp"

#include "st/common/error.hpp"

namespace st::search {
namespace {

class FallbackBackend final : public SearchBackend {
 public:
  FallbackBackend(std::unique_ptr<SearchBackend> primary, std::unique_ptr<SearchBackend> fallback)
      : m_primary(std::move(primary)), m_fallback(std::move(fallback)) {}

  [[nodiscard]] std::string name() const override { return current().name(); }
  [[nodiscard]] bool supportsMethod(const std::string& method) const override {
    return current().supportsMethod(method);
  }

  SearchResult search(const FilteredCube& cube, const VelocityGrid& grid, const SearchParams& params,
                      ProgressSink& progress, CancelToken& cancel) override {
    if (!m_failure.empty()) return onFallback(m_fallback->search(cube, grid, params, progress, cancel));
    try {
      return m_primary->search(cube, grid, params, progress, cancel);
    } catch (const GpuError& e) {
      fail(e);
    }
    return onFallback(m_fallback->search(cube, grid, params, progress, cancel));
  }

  Image stackAt(const FilteredCube& cube, Velocity v, StackMode mode) override {
    if (m_failure.empty()) {
      try {
        return m_primary->stackAt(cube, v, mode);
      } catch (const GpuError& e) {
        fail(e);
      }
    }
    return m_fallback->stackAt(cube, v, mode);
  }

 private:
  [[nodiscard]] const SearchBackend& current() const { return m_failure.empty() ? *m_primary : *m_fallback; }
  void fail(const GpuError& e) {
    m_failure =
        m_primary->name() + " failed (" + e.what() + "); searched on " + m_fallback->name() + " instead";
  }
  SearchResult onFallback(SearchResult r) const {
    r.warnings.insert(r.warnings.begin(), m_failure);
    return r;
  }

  std::unique_ptr<SearchBackend> m_primary;
  std::unique_ptr<SearchBackend> m_fallback;
  std::string m_failure;  ///< empty until the primary fails
};

}  // namespace

std::unique_ptr<SearchBackend> makeFallbackBackend(std::unique_ptr<SearchBackend> primary,
                                                   std::unique_ptr<SearchBackend> fallback) {
  return std::make_unique<FallbackBackend>(std::move(primary), std::move(fallback));
}

}  // namespace st::search
