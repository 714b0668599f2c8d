// The backend factory's helpers that need no GPU: the device names for the GUI's backend list, parsed from
// st::gpu::deviceSummary()'s text, and the backend for a method (the CPU has both methods).
#include <gtest/gtest.h>

#include "backend_factory.hpp"

namespace st::app {
namespace {

TEST(BackendFactory, DeviceNamesFromTheSummary) {
  const auto names =
      parseDeviceSummary("0: NVIDIA H100 80GB HBM3, 79.1 GiB, sm_90\n1: NVIDIA H200, 139.8 GiB, sm_90\n");
  ASSERT_EQ(names.size(), 2u);
  EXPECT_EQ(names[0], "NVIDIA H100 80GB HBM3, 79.1 GiB");
  EXPECT_EQ(names[1], "NVIDIA H200, 139.8 GiB");
  EXPECT_TRUE(parseDeviceSummary("no CUDA device: CUDA driver version is insufficient").empty());
  EXPECT_TRUE(parseDeviceSummary("no CUDA device").empty());
  EXPECT_TRUE(parseDeviceSummary("").empty());
}

TEST(BackendFactory, TreeRequestGetsABackendWithTheTree) {
  // Whatever Auto finds (a GPU without the tree falls back to the CPU), the backend runs the tree.
  const BackendSelection sel = makeBackendForMethod(BackendChoice::Auto, "tree");
  ASSERT_TRUE(sel.backend);
  EXPECT_TRUE(sel.backend->supportsMethod("tree")) << sel.message;
  EXPECT_TRUE(makeBackendForMethod(BackendChoice::Cpu, "exact").backend->supportsMethod("exact"));
}

}  // namespace
}  // namespace st::app
