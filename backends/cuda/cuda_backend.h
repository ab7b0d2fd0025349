// The CUDA backend (also compiles under HIP). Plain C++ header: no GPU types leak out.
#pragma once

#include <memory>
#include <string>

#include "lblight/backend/backend.h"

namespace lblight {

// "" when a GPU is usable, else why not (no driver, no device, ...).
std::string cuda_unavailable_reason();
std::unique_ptr<Backend> make_cuda_backend(int device);

}  // namespace lblight
