#pragma once
// The one place a search backend is chosen (ARCHITECTURE.md): the GUI and the CLI both call this.
#include <functional>
#include <future>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "st/pipeline/preprocess_accelerator.hpp"
#include "st/search/types.hpp"

namespace st::app {

enum class BackendChoice { Auto, Cpu, Cuda };

/// Parses "auto", "cpu" or "cuda"; throws st::InputError naming the value otherwise.
BackendChoice parseBackendChoice(const std::string& text);

/// How the CUDA backend stores the filtered frames for the exact search (gpu::FramePrecision): fp32 (the
/// default, the CPU's sums to float rounding) or fp16 (a half copy summed in half pairs per pipeline stage,
/// 1.27x faster on the paper's problem, SNR within ~1e-3 of fp32). The CPU backend searches in float32.
enum class FramePrecisionChoice { Fp32, Fp16 };

/// Parses "fp32" or "fp16"; throws st::InputError naming the value otherwise.
FramePrecisionChoice parseFramePrecision(const std::string& text);

/// What fp16 frames cost in SNR, for the user (measured bound, device and date).
std::string framePrecisionNote(FramePrecisionChoice precision);

struct BackendSelection {
  std::unique_ptr<search::SearchBackend> backend;
  std::string message;  ///< what was chosen and, on a fallback, why (shown to the user)
};

/// Auto: CUDA when a usable device is there, else the CPU with the reason in `message`. Cuda: the CUDA
/// backend, or st::GpuError when it cannot be had. Cpu: the CPU backend.
/// `precision` applies to the CUDA backend (the message says what it costs, or that the CPU ignores it).
BackendSelection makeBackend(BackendChoice choice,
                             FramePrecisionChoice precision = FramePrecisionChoice::Fp32);

/// makeBackend(choice) for a search with SearchParams::method `method` (Auto, Exact, Tree): a tree
/// request on a backend without the tree (SearchBackend::supportsMethod) gets the CPU backend when the
/// backend was chosen automatically (the message says why), and st::InputError naming the backend when it was
/// named.
BackendSelection makeBackendForMethod(BackendChoice choice, search::SearchMethod method,
                                      FramePrecisionChoice precision = FramePrecisionChoice::Fp32);

/// makeBackendForMethod on another thread (a CUDA context takes ~0.2 s: issue 16 makes it while the frames
/// are read or simulated); get() waits for it once and rethrows what the making threw.
class BackendInTheMaking {
 public:
  BackendInTheMaking(BackendChoice choice, search::SearchMethod method,
                     FramePrecisionChoice precision = FramePrecisionChoice::Fp32);
  BackendSelection& get();

 private:
  std::future<BackendSelection> m_future;
  std::optional<BackendSelection> m_made;
};

/// For one of `localWorkers` worker processes on a node (batch under MPI), index `localIndex`: each gets
/// its own GPU when the node has several (CUDA_VISIBLE_DEVICES set to one of the visible ones, round robin;
/// the devices counted from CUDA_VISIBLE_DEVICES or /dev/nvidiaN, without starting CUDA, so call this
/// before any backend is made), and a share of the cores (ST_THREADS = cores / workers on the node) unless
/// ST_THREADS is set. Returns what was chosen, for the log.
std::string chooseRankResources(int localIndex, int localWorkers);

/// What a finished search has to tell the user besides its candidates, for a terminal: each of
/// SearchResult::warnings as "warning: ...", then the backend's note (memory tiling, devices, time per
/// phase) indented; empty when there is neither.
std::string searchNotesText(const search::SearchResult& result);

/// The names of the visible GPUs for a backend selector ("NVIDIA H100 80GB HBM3, 79.1 GiB"), empty without
/// CUDA or a device.
std::vector<std::string> gpuNames();

/// The device names in the text of st::gpu::deviceSummary() (lines "0: NAME, 79.1 GiB, sm_90"): "NAME, 79.1
/// GiB" per device line; lines of another form (e.g. "no CUDA device: ...") are skipped.
std::vector<std::string> parseDeviceSummary(const std::string& summary);

/// The device for the pre-processing's per-pixel background and matched filter (issue 16) that goes with a
/// search on `backend`: the CUDA one when the backend is CUDA (its name starts with "cuda") and a device is
/// usable, else null (the CPU). `message` says which, for the log.
std::unique_ptr<pipeline::PreprocessAccelerator> makePreprocessAccelerator(
    const search::SearchBackend& backend, std::string& message);

/// Whether this build has the CUDA backend compiled in.
bool cudaCompiledIn();

}  // namespace st::app
