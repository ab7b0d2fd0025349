// Compiled only by scripts/hip-compile-check.sh (HIP for gfx90a, no GPU needed): the gas solver's
// per-node update (lblight/fluid/gas_node.h) inside kernels, one thread per node, proving it is
// device code as lattice/collide.h is. The loop that launches them is not written yet
// (docs/fluid.md).
#include "backends/cuda/gpu_runtime.h"  // the HIP runtime under hipcc
#include "lblight/fluid/gas_node.h"

namespace {

using namespace lblight::fluid;

__global__ void collide_kernel(GasView v) {
  const std::size_t i = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i < v.n) collide_node(v, i);
}

template <int Q>
__global__ void stream_kernel(GasView v, GasLattice lattice, const float* post, float* next) {
  const std::size_t i = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= v.n) return;
  const int x = static_cast<int>(i % v.nx), y = static_cast<int>(i / v.nx % v.ny);
  const int z = static_cast<int>(i / (static_cast<std::size_t>(v.nx) * v.ny));
  stream_node<Q>(v, lattice, post, next, x, y, z);
}

}  // namespace

// One step as four launches (collide, then the flow, temperature and smoke streamed).
void gas_step_launches(const GasView& v, float* f, float* t, float* c) {
  const unsigned blocks = static_cast<unsigned>((v.n + 127) / 128);
  collide_kernel<<<blocks, 128>>>(v);
  stream_kernel<lblight::d3q19::kQ><<<blocks, 128>>>(v, kFlowLattice, v.f_post, f);
  stream_kernel<kQ7><<<blocks, 128>>>(v, kTemperatureLattice, v.t_post, t);
  stream_kernel<kQ7><<<blocks, 128>>>(v, kSmokeLattice, v.c_post, c);
}
