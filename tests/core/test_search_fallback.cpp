// The fallback backend (fallback_backend.hpp, issue 5): a device failure reruns the search on the CPU with
// the same result as the CPU alone and a warning naming the failed backend and its error; later calls go to
// the CPU; cancellation and bad input are not "device failures" and pass through.
#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "search_test_cubes.hpp"
#include "st/common/error.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/search/fallback_backend.hpp"

namespace st::search {
namespace {

/// A "GPU" that fails with the error given, counting its calls.
class FailingBackend final : public SearchBackend {
 public:
  enum class Failure { Device, Cancel, Input };
  FailingBackend(Failure f, int* calls) : m_failure(f), m_calls(calls) {}
  [[nodiscard]] std::string name() const override { return "cuda: test device"; }
  SearchResult search(const FilteredCube&, const VelocityGrid&, const SearchParams&, ProgressSink&,
                      CancelToken&) override {
    fail();
    return {};
  }
  Image stackAt(const FilteredCube&, Velocity, StackMode) override {
    fail();
    return {};
  }

 private:
  void fail() {
    ++*m_calls;
    if (m_failure == Failure::Cancel) throw Cancelled();
    if (m_failure == Failure::Input) throw InputError("bad grid");
    throw GpuError("cudaMalloc(2147483648 bytes): out of memory");
  }
  Failure m_failure;
  int* m_calls;
};

FilteredCube smallCube() {
  FilteredCube fc;
  fc.frames = test::noiseCube(24, 20, test::unevenTimes(12, 0.7, 3, false), 1.0, 3);
  fc.sigmaF = 1.0;
  return fc;
}

TEST(FallbackBackend, DeviceFailureGivesTheCpuResultWithAWarningAndStaysOnTheCpu) {
  const FilteredCube fc = smallCube();
  const VelocityGrid grid{{0.0, 0.0}, 0.3, 5, 5};
  SearchParams params;
  params.snrThreshold = 3.0;
  NullProgress progress;
  CancelToken cancel;
  const SearchResult cpu = makeCpuBackend()->search(fc, grid, params, progress, cancel);
  ASSERT_FALSE(cpu.candidates.empty());

  int calls = 0;
  auto backend = makeFallbackBackend(
      std::make_unique<FailingBackend>(FailingBackend::Failure::Device, &calls), makeCpuBackend());
  EXPECT_EQ(backend->name(), "cuda: test device");
  const SearchResult r = backend->search(fc, grid, params, progress, cancel);
  EXPECT_EQ(calls, 1);
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("cuda: test device failed"), std::string::npos) << r.warnings[0];
  EXPECT_NE(r.warnings[0].find("out of memory"), std::string::npos) << r.warnings[0];
  EXPECT_NE(r.warnings[0].find(makeCpuBackend()->name()), std::string::npos) << r.warnings[0];
  EXPECT_EQ(r.backend, cpu.backend);
  ASSERT_EQ(r.candidates.size(), cpu.candidates.size());
  for (std::size_t i = 0; i < r.candidates.size(); ++i) {
    EXPECT_EQ(r.candidates[i].x, cpu.candidates[i].x);
    EXPECT_EQ(r.candidates[i].y, cpu.candidates[i].y);
    EXPECT_EQ(r.candidates[i].snr, cpu.candidates[i].snr);
  }
  EXPECT_EQ(r.map.maxSnr, cpu.map.maxSnr);

  // The device is not tried again; the warning still says why the CPU ran.
  EXPECT_NE(backend->name().rfind("cuda", 0), 0u);
  const SearchResult again = backend->search(fc, grid, params, progress, cancel);
  EXPECT_EQ(calls, 1);
  ASSERT_EQ(again.warnings.size(), 1u);
  const Image s = backend->stackAt(fc, {0.1, -0.2}, StackMode::Ipsa);
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(s.pixels, makeCpuBackend()->stackAt(fc, {0.1, -0.2}, StackMode::Ipsa).pixels);
}

TEST(FallbackBackend, StackAtFallsBackToo) {
  const FilteredCube fc = smallCube();
  int calls = 0;
  auto backend = makeFallbackBackend(
      std::make_unique<FailingBackend>(FailingBackend::Failure::Device, &calls), makeCpuBackend());
  const Image s = backend->stackAt(fc, {0.2, 0.1}, StackMode::Ipsa);
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(s.pixels, makeCpuBackend()->stackAt(fc, {0.2, 0.1}, StackMode::Ipsa).pixels);
}

TEST(FallbackBackend, CancelAndBadInputPassThrough) {
  const FilteredCube fc = smallCube();
  const VelocityGrid grid{{0.0, 0.0}, 0.3, 5, 5};
  NullProgress progress;
  CancelToken cancel;
  int calls = 0;
  auto cancelled = makeFallbackBackend(
      std::make_unique<FailingBackend>(FailingBackend::Failure::Cancel, &calls), makeCpuBackend());
  EXPECT_THROW(cancelled->search(fc, grid, {}, progress, cancel), Cancelled);
  EXPECT_EQ(cancelled->name(), "cuda: test device");  // still the device: it did not fail
  auto bad = makeFallbackBackend(std::make_unique<FailingBackend>(FailingBackend::Failure::Input, &calls),
                                 makeCpuBackend());
  EXPECT_THROW(bad->search(fc, grid, {}, progress, cancel), InputError);
  EXPECT_EQ(calls, 2);
}

}  // namespace
}  // namespace st::search
