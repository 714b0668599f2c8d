#pragma once
// The device-or-skip line of the GPU pre-processing tests: `var` becomes the CUDA pre-processing accelerator,
// or the test is skipped naming why there is none (CI has no GPU).
#include <gtest/gtest.h>

#include <string>

#include "st/gpu/preprocess.hpp"

#define ST_REQUIRE_GPU_PREPROCESS(var)                    \
  std::string whyNot_;                                    \
  auto var = gpu::makeCudaPreprocessAccelerator(whyNot_); \
  if (!var) GTEST_SKIP() << "no usable CUDA device: " << whyNot_;
