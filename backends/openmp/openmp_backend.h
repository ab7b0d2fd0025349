#pragma once

#include <memory>

#include "lblight/backend/backend.h"

namespace lblight {

// The layer exchange a slab decomposition along z needs (backends/mpi): the CPU solver pulls, so
// the state it keeps at node q is q's post-collision light, g_m(q), which node q + c_m takes in
// the next step. A slab's first and last layers are its neighbours' (ghosts, fixed like any
// boundary node by the solver); before their neighbouring layers are swept they receive the
// neighbours' g for the 5 directions that cross into the slab. Values are the interior nodes (x, y) of one layer, for the
// 5 directions m with c_m,z == sign, direction by direction, row by row, in the storage's own
// values converted to double (exactly).
class SlabHalo {
 public:
  virtual ~SlabHalo() = default;
  static std::size_t layer_values(const Dims& d) { return 5 * static_cast<std::size_t>(d.nx - 2) * (d.ny - 2); }
  // The last measure()'s sums (backend/node_rules.h, kReduceSlots per layer) for each interior
  // layer z = 1 .. nz - 2 in turn: the solver's residual is these combined in z order.
  virtual const double* layer_sums(int system) const = 0;
  // One step in parts, so that messages can travel meanwhile: step_layers sweeps layers
  // z_lo..z_hi of every system (from the current level into the next), end_step then makes the
  // next level current. Sweeping every interior layer once between end_steps is step(1).
  virtual void step_layers(int z_lo, int z_hi) = 0;
  virtual void end_step() = 0;
  virtual void read_layer(int system, int z, int sign, double* out) const = 0;
  virtual void write_layer(int system, int z, int sign, const double* in) = 0;
};

// The CPU backend: OpenMP threads over lattice rows, SIMD along x. threads = 0 keeps OpenMP's
// default (OMP_NUM_THREADS or all cores).
std::unique_ptr<Backend> make_openmp_backend(int threads);

}  // namespace lblight
