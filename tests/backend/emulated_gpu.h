// The CUDA backend on the CPU: its solver (backends/cuda/gpu_solver.h) over an emulated device
// whose launches are loops over the same launch grids, each thread running the same per-thread
// code (backends/cuda/lb_device.h) as the kernels. The conformance cases run on it on every
// machine, so the GPU backend's host side and kernel code are checked even where no GPU is
// (tests/backend/conformance.cpp). Only the CUDA API calls and the kernels' shells are not.
#pragma once

#include <memory>

#include "backends/cuda/lb_device.h"
#include "lblight/backend/backend.h"

namespace lblight::test {

// fill: step_launch's fill_threads (fewer than the default puts more systems on each thread).
// Stores float32, and float16 where the compiler has _Float16 (it rounds as __float2half_rn).
std::unique_ptr<Backend> make_emulated_gpu_backend(long long fill = gpu::kStepFillThreads);

// Every thread of the step launch step_launch(d, systems, fill) lays out, block by block, as
// step_kernel runs them: node(x, y, z, s_begin, s_end) for each thread on an interior node.
template <typename Node>
void for_each_step_thread(const Dims& d, int systems, long long fill, Node&& node) {
  const gpu::StepLaunch l = gpu::step_launch(d, systems, fill);
  for (unsigned bz = 0; bz < l.gz; ++bz)
    for (unsigned by = 0; by < l.gy; ++by)
      for (unsigned bx = 0; bx < l.gx; ++bx)
        for (unsigned ty = 0; ty < static_cast<unsigned>(l.by); ++ty)
          for (unsigned tx = 0; tx < static_cast<unsigned>(l.bx); ++tx) {
            int x, y, z, s0, s1;
            if (l.by == 1 ? gpu::step_thread_node<true>(d, l.per_group, systems, bx, by, bz, l.bx, l.by, tx, ty, x,
                                                        y, z, s0, s1)
                          : gpu::step_thread_node<false>(d, l.per_group, systems, bx, by, bz, l.bx, l.by, tx, ty, x,
                                                         y, z, s0, s1))
              node(x, y, z, s0, s1);
          }
}

// Every node of the inflow launch inflow_launch(d) lays out, block by block, as inflow_kernel
// runs them.
template <typename Node>
void for_each_inflow_node(const Dims& d, Node&& node) {
  const gpu::InflowLaunch l = gpu::inflow_launch(d);
  for (long long b = 0; b < l.blocks; ++b)
    for (int tx = 0; tx < gpu::kInflowThreads; ++tx) gpu::inflow_thread_nodes(d, l, b, tx, gpu::kInflowThreads, node);
}

}  // namespace lblight::test
