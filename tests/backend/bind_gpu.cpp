// The conformance cases of lblight_gpu_tests: the CUDA backend on device 0, with two levels of
// state and in place.
#include "backends/cuda/cuda_backend.h"
#include "tests/backend/conformance.h"

namespace lblight::test {

std::vector<BoundBackend> conformance_backends() {
  std::shared_ptr<Backend> cuda = make_cuda_backend(0);
  return {{"cuda", cuda}, {"cuda, in place", in_place(cuda)}};
}

}  // namespace lblight::test
