#include "backend_factory.hpp"

#include <cstdio>
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <regex>
#include <thread>

#include "st/common/error.hpp"
#include "st/config.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/search/fallback_backend.hpp"
#if ST_HAVE_CUDA
#include "st/gpu/cuda_backend.hpp"
#include "st/gpu/preprocess.hpp"
#endif

namespace st::app {

BackendChoice parseBackendChoice(const std::string& text) {
  if (text == "auto") return BackendChoice::Auto;
  if (text == "cpu") return BackendChoice::Cpu;
  if (text == "cuda" || text == "gpu") return BackendChoice::Cuda;
  throw InputError("backend must be auto, cpu or cuda, got '" + text + "'");
}

FramePrecisionChoice parseFramePrecision(const std::string& text) {
  if (text == "fp32" || text == "float32") return FramePrecisionChoice::Fp32;
  if (text == "fp16" || text == "float16") return FramePrecisionChoice::Fp16;
  throw InputError("frame precision must be fp32 or fp16, got '" + text + "'");
}

std::string framePrecisionNote(FramePrecisionChoice precision) {
  if (precision == FramePrecisionChoice::Fp32) return "frames in float32";
  // gpu/README.md "Float16 frames": st_gpu_bench 1500 512 100 12 500 half, H100, 2026-11-27.
  return "frames in float16 on the GPU (exact search, stair kernel): SNR differs from float32 by at most "
         "6.4e-4 relative over the paper's velocity map (mean 1.2e-4, 2.6e-5 at the injected object; H100, "
         "2026-11-27), values beyond +-2048 sigma_F are clipped; 1.27x the float32 search's speed";
}

bool cudaCompiledIn() {
  return ST_HAVE_CUDA != 0;
}

std::unique_ptr<pipeline::PreprocessAccelerator> makePreprocessAccelerator(
    const search::SearchBackend& backend, std::string& message) {
  if (backend.name().rfind("cuda", 0) != 0) {
    message = "pre-processing on the CPU";
    return nullptr;
  }
#if ST_HAVE_CUDA
  std::string whyNot;
  auto accel = gpu::makeCudaPreprocessAccelerator(whyNot);
  if (accel) {
    message = "per-pixel background and matched filter on " + accel->name();
    return accel;
  }
  message = "pre-processing on the CPU (" + whyNot + ")";
#else
  message = "pre-processing on the CPU";
#endif
  return nullptr;
}

BackendSelection makeBackend(BackendChoice choice, FramePrecisionChoice precision) {
  BackendSelection out;
  const bool half = precision == FramePrecisionChoice::Fp16;
  if (choice != BackendChoice::Cpu) {
    std::string whyNot;
#if ST_HAVE_CUDA
    gpu::CudaOptions options;
    options.precision = half ? gpu::FramePrecision::Float16 : gpu::FramePrecision::Float32;
    out.backend = gpu::makeCudaSearchBackend(whyNot, options);
    // The staging buffers of pre-processing's first upload pinned now (beside the frames' read when the
    // backend is made behind it, BackendInTheMaking): its upload then does not wait for them.
    if (out.backend) gpu::warmPreprocessStaging();
#else
    whyNot = "this build has no CUDA backend (built without nvcc)";
#endif
    if (out.backend) {
      out.message = "using " + out.backend->name();
      if (half) out.message += "; " + framePrecisionNote(precision);
      // A device failure during a search (out of memory, a failed launch) reruns it on the CPU, saying so.
      out.backend = search::makeFallbackBackend(std::move(out.backend), search::makeCpuBackend());
      return out;
    }
    if (choice == BackendChoice::Cuda) throw GpuError("CUDA backend not available: " + whyNot);
    out.message = "GPU not used (" + whyNot + "); ";
  }
  out.backend = search::makeCpuBackend();
  out.message += "using " + out.backend->name();
  if (half) out.message += " (frame precision fp16 applies to the CUDA backend only: float32 here)";
  return out;
}

BackendSelection makeBackendForMethod(BackendChoice choice, search::SearchMethod method,
                                      FramePrecisionChoice precision) {
  BackendSelection sel = makeBackend(choice, precision);
  if (method != search::SearchMethod::Tree || sel.backend->supports(search::SearchMethod::Tree)) return sel;
  if (choice == BackendChoice::Cuda) {
    throw InputError("the tree search is not available on " + sel.backend->name() +
                     ": use the CPU backend, or method auto or exact");
  }
  const std::string gpu = sel.backend->name();
  sel = makeBackend(BackendChoice::Cpu);
  sel.message = "method tree: " + gpu + " has no tree search; " + sel.message;
  return sel;
}

BackendInTheMaking::BackendInTheMaking(BackendChoice choice, search::SearchMethod method,
                                       FramePrecisionChoice precision)
    : m_future(
          std::async(std::launch::async, [=] { return makeBackendForMethod(choice, method, precision); })) {
  // What needs no driver is said at once (the rest when the backend is first asked for).
  if (choice == BackendChoice::Cuda && !cudaCompiledIn()) {
    m_future.wait();
    m_made = m_future.get();  // throws makeBackend's GpuError
  }
}

BackendSelection& BackendInTheMaking::get() {
  if (!m_made) m_made = m_future.get();
  return *m_made;
}

std::string chooseRankResources(int localIndex, int localWorkers) {
  localWorkers = std::max(1, localWorkers);
  std::vector<std::string> devices;
  if (const char* v = std::getenv("CUDA_VISIBLE_DEVICES")) {
    std::string list = v;
    for (std::size_t start = 0; start <= list.size();) {
      const std::size_t comma = std::min(list.find(',', start), list.size());
      if (comma > start) devices.push_back(list.substr(start, comma - start));
      start = comma + 1;
    }
  } else {
    std::error_code ec;
    const std::regex gpu("nvidia[0-9]+");
    for (const auto& e : std::filesystem::directory_iterator("/dev", ec)) {
      const std::string name = e.path().filename().string();
      if (std::regex_match(name, gpu)) devices.push_back(name.substr(6));
    }
    std::sort(devices.begin(), devices.end());
  }
  std::string note;
  if (cudaCompiledIn() && devices.size() > 1) {
    const std::string mine = devices[static_cast<std::size_t>(localIndex) % devices.size()];
    ::setenv("CUDA_VISIBLE_DEVICES", mine.c_str(), 1);
    note = "GPU " + mine + " of " + std::to_string(devices.size());
  } else {
    note = devices.empty() ? "no GPU" : std::to_string(devices.size()) + " GPU(s) visible";
  }
  if (std::getenv("ST_THREADS") == nullptr) {
    const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
    const unsigned share = std::max(1u, cores / static_cast<unsigned>(localWorkers));
    ::setenv("ST_THREADS", std::to_string(share).c_str(), 1);
  }
  return note + ", " + std::getenv("ST_THREADS") + " CPU threads";
}

std::string searchNotesText(const search::SearchResult& result) {
  std::string out;
  for (const std::string& w : result.warnings)
    out += "warning: " + w + "\n";
  std::size_t start = 0;
  while (start < result.backendNote.size()) {
    std::size_t end = result.backendNote.find('\n', start);
    if (end == std::string::npos) end = result.backendNote.size();
    out += "  " + result.backendNote.substr(start, end - start) + "\n";
    start = end + 1;
  }
  if (!result.staticSources.empty()) {
    char line[200];
    std::snprintf(line, sizeof line,
                  "note: %zu candidate(s) at the sky rate (best SNR %.1f) set aside as static sources, not "
                  "movers (JSON: static_sources)\n",
                  result.staticSources.size(), result.staticSources.front().snr);
    out += line;
  }
  return out;
}

std::vector<std::string> parseDeviceSummary(const std::string& summary) {
  std::vector<std::string> names;
  std::size_t start = 0;
  while (start < summary.size()) {
    std::size_t end = summary.find('\n', start);
    if (end == std::string::npos) end = summary.size();
    const std::string line = summary.substr(start, end - start);
    start = end + 1;
    const std::size_t colon = line.find(": ");
    const std::size_t sm = line.rfind(", sm_");
    if (colon == std::string::npos || sm == std::string::npos || sm <= colon + 2) continue;
    if (line.find_first_not_of("0123456789") != colon) continue;  // "N: ..." only
    names.push_back(line.substr(colon + 2, sm - colon - 2));
  }
  return names;
}

std::vector<std::string> gpuNames() {
#if ST_HAVE_CUDA
  return parseDeviceSummary(gpu::deviceSummary());
#else
  return {};
#endif
}

}  // namespace st::app
