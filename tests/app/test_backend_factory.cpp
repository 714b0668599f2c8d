// The backend factory's helpers that need no GPU: the device names for the GUI's backend list, parsed from
// st::gpu::deviceSummary()'s text, and the backend for a method (the CPU has both methods).
#include <gtest/gtest.h>

#include "backend_factory.hpp"
#include "st/common/error.hpp"

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

// --frame-precision (issue 16): fp32 and fp16 parse, anything else is refused naming the value; the CPU
// backend says it ignores fp16; with a device, the CUDA backend's message gives fp16's SNR cost.
TEST(BackendFactory, FramePrecisionParsesAndSaysWhatItCosts) {
  EXPECT_EQ(parseFramePrecision("fp32"), FramePrecisionChoice::Fp32);
  EXPECT_EQ(parseFramePrecision("fp16"), FramePrecisionChoice::Fp16);
  try {
    parseFramePrecision("fp8");
    ADD_FAILURE() << "fp8 accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'fp8'"), std::string::npos) << e.what();
  }
  const BackendSelection cpu = makeBackend(BackendChoice::Cpu, FramePrecisionChoice::Fp16);
  EXPECT_NE(cpu.message.find("CUDA backend only"), std::string::npos) << cpu.message;
  EXPECT_EQ(makeBackend(BackendChoice::Cpu).message.find("fp16"), std::string::npos);
  EXPECT_NE(framePrecisionNote(FramePrecisionChoice::Fp16).find("6.4e-4"), std::string::npos);
  const BackendSelection any = makeBackend(BackendChoice::Auto, FramePrecisionChoice::Fp16);
  if (any.message.rfind("using cuda", 0) == 0) {
    EXPECT_NE(any.message.find("float16"), std::string::npos) << any.message;
  }
}

}  // namespace
}  // namespace st::app
