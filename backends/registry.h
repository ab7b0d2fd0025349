// The one place that picks a backend by name. It sits with the backends, above the library:
// lblight/ only knows the interface (lblight/backend/backend.h), never a backend.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "lblight/backend/backend.h"

namespace lblight {

struct BackendRequest {
  std::string name = "auto";  // auto | cpu | cuda | mpi
  int threads = 0;            // CPU threads; 0 = all cores (or OMP_NUM_THREADS)
  int device = 0;             // GPU ordinal
};

// Why the CUDA backend cannot run here ("" when it can).
std::string gpu_unavailable_reason();

// "auto" picks the GPU when one is usable and logs the choice; an explicit name that cannot run
// throws Error(Unavailable) with the reason.
std::unique_ptr<Backend> make_backend(const BackendRequest& request);

}  // namespace lblight
