#pragma once
// The one place a search backend is chosen (ARCHITECTURE.md): the GUI and the CLI both call this.
#include <memory>
#include <string>

#include "st/search/types.hpp"

namespace st::app {

enum class BackendChoice { Auto, Cpu, Cuda };

/// Parses "auto", "cpu" or "cuda"; throws st::InputError naming the value otherwise.
BackendChoice parseBackendChoice(const std::string& text);

struct BackendSelection {
  std::unique_ptr<search::SearchBackend> backend;
  std::string message;  ///< what was chosen and, on a fallback, why (shown to the user)
};

/// Auto: CUDA when a usable device is there, else the CPU with the reason in `message`. Cuda: the CUDA
/// backend, or st::GpuError when it cannot be had. Cpu: the CPU backend.
BackendSelection makeBackend(BackendChoice choice);

/// Whether this build has the CUDA backend compiled in.
bool cudaCompiledIn();

}  // namespace st::app
