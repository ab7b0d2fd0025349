// The backend conformance cases (conformance.cpp) are written once and bound to every backend a
// test executable has: the OpenMP backend and the emulated GPU in lblight_tests
// (bind_cpu.cpp), the CUDA backend in lblight_gpu_tests (bind_gpu.cpp).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "lblight/backend/backend.h"

namespace lblight::test {

struct BoundBackend {
  std::string label;  // for messages: "cpu", "emulated-gpu (3 system groups)", "cuda"
  std::shared_ptr<Backend> backend;
};

std::vector<BoundBackend> conformance_backends();

// `inner` creating every solver with one level of state, updated in place (StateLayout::InPlace).
std::shared_ptr<Backend> in_place(std::shared_ptr<Backend> inner);

}  // namespace lblight::test
