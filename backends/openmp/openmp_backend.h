#pragma once

#include <memory>

#include "lblight/backend/backend.h"

namespace lblight {

// The CPU backend: OpenMP threads over lattice rows, SIMD along x. threads = 0 keeps OpenMP's
// default (OMP_NUM_THREADS or all cores).
std::unique_ptr<Backend> make_openmp_backend(int threads);

}  // namespace lblight
