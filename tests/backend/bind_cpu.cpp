// The conformance cases of lblight_tests: the OpenMP backend on 1 and 2 threads, and with its
// state updated in place (StateLayout::InPlace), and the CUDA backend's kernels emulated on the
// CPU, with the default launch (on small lattices a batch's systems split into groups of threads),
// with every system of a batch on each thread, and in place.
#include "tests/backend/conformance.h"
#include "tests/backend/emulated_gpu.h"
#include "tests/support/test_support.h"

namespace lblight::test {

std::vector<BoundBackend> conformance_backends() {
  return {{"cpu, 1 thread", cpu_backend(1)},
          {"cpu, 2 threads", cpu_backend(2)},
          {"cpu, in place", in_place(cpu_backend(2))},
          {"emulated-gpu", make_emulated_gpu_backend()},
          {"emulated-gpu, all of a batch's systems on each thread", make_emulated_gpu_backend(1)},
          {"emulated-gpu, in place", in_place(make_emulated_gpu_backend())}};
}

}  // namespace lblight::test
