// The conformance cases of lblight_gpu_tests: the CUDA backend on device 0.
#include "backends/cuda/cuda_backend.h"
#include "tests/backend/conformance.h"

namespace lblight::test {

std::vector<BoundBackend> conformance_backends() { return {{"cuda", make_cuda_backend(0)}}; }

}  // namespace lblight::test
