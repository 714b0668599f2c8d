#pragma once
// Pre-processing on the GPU (issue 16): the per-pixel background and the matched filter of the pipeline
// (st::pipeline::PreprocessAccelerator) on the first usable device. The filtered cube it makes stays on the
// device, where the CUDA search backend's exact and tree searches and stackAt find it without an upload.
#include <memory>
#include <string>

#include "st/pipeline/preprocess_accelerator.hpp"

namespace st::gpu {

class CudaPreprocessAccelerator : public pipeline::PreprocessAccelerator {
 public:
  /// Keep the matched filter's output resident for the search (default on).
  virtual void setKeepResident(bool keep) = 0;
};

/// Pins the four staging buffers that the next accelerator's copies take (its stages' two and the two of the
/// downloads behind them; cudaMallocHost of 64 MiB: 29-73 ms on H100 hosts), ahead of it: the app calls it
/// where it makes the CUDA search backend, beside the frames' read. Never throws (a failure leaves the
/// accelerator to pin its own).
void warmPreprocessStaging() noexcept;

/// The accelerator on the first device of compute capability 9.0 or newer, or nullptr with `whyNot` set.
std::unique_ptr<CudaPreprocessAccelerator> makeCudaPreprocessAccelerator(std::string& whyNot);

}  // namespace st::gpu
