#include "backends/registry.h"

#include <spdlog/spdlog.h>

#include "backends/openmp/openmp_backend.h"
#include "lblight/core/error.h"

#if LBLIGHT_WITH_CUDA
#include "backends/cuda/cuda_backend.h"
#endif
#if LBLIGHT_WITH_MPI
#include "backends/mpi/mpi_backend.h"
#endif

namespace lblight {

std::string gpu_unavailable_reason() {
#if LBLIGHT_WITH_CUDA
  return cuda_unavailable_reason();
#else
  return "this lblight was built without the CUDA backend (nvcc was not found at build time)";
#endif
}

std::unique_ptr<Backend> make_backend(const BackendRequest& req) {
  if (req.name == "cpu") return make_openmp_backend(req.threads);
  if (req.name == "mpi") {
#if LBLIGHT_WITH_MPI
    return make_mpi_backend(req.threads);
#else
    throw Error(ErrorCategory::Unavailable,
                "--backend mpi cannot run: this lblight was built without MPI (install libopenmpi-dev and rebuild; "
                "docs/scale-out.md)");
#endif
  }
  if (req.name == "cuda") {
    const std::string why = gpu_unavailable_reason();
    if (!why.empty()) throw Error(ErrorCategory::Unavailable, "--backend cuda cannot run: " + why);
#if LBLIGHT_WITH_CUDA
    return make_cuda_backend(req.device);
#endif
  }
  if (req.name == "auto") {
    const std::string why = gpu_unavailable_reason();
    if (why.empty()) {
#if LBLIGHT_WITH_CUDA
      auto b = make_cuda_backend(req.device);
      spdlog::info("backend auto: using the GPU ({})", b->description());
      return b;
#endif
    }
    spdlog::info("backend auto: using the CPU ({})", why);
    return make_openmp_backend(req.threads);
  }
  throw_invalid("unknown backend '" + req.name + "'; allowed: auto, cpu, cuda, mpi");
}

}  // namespace lblight
