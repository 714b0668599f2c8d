#include "backend_factory.hpp"

#include "st/common/error.hpp"
#include "st/config.hpp"
#include "st/search/cpu_backend.hpp"
#if ST_HAVE_CUDA
#include "st/gpu/cuda_backend.hpp"
#endif

namespace st::app {

BackendChoice parseBackendChoice(const std::string& text) {
  if (text == "auto") return BackendChoice::Auto;
  if (text == "cpu") return BackendChoice::Cpu;
  if (text == "cuda" || text == "gpu") return BackendChoice::Cuda;
  throw InputError("backend must be auto, cpu or cuda, got '" + text + "'");
}

bool cudaCompiledIn() {
  return ST_HAVE_CUDA != 0;
}

BackendSelection makeBackend(BackendChoice choice) {
  BackendSelection out;
  if (choice != BackendChoice::Cpu) {
    std::string whyNot;
#if ST_HAVE_CUDA
    out.backend = gpu::makeCudaBackend(whyNot);
#else
    whyNot = "this build has no CUDA backend (built without nvcc)";
#endif
    if (out.backend) {
      out.message = "using " + out.backend->name();
      return out;
    }
    if (choice == BackendChoice::Cuda) throw GpuError("CUDA backend not available: " + whyNot);
    out.message = "GPU not used (" + whyNot + "); ";
  }
  out.backend = search::makeCpuBackend();
  out.message += "using " + out.backend->name();
  return out;
}

}  // namespace st::app
