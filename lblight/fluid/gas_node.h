// What one node of the gas solver does in a step ([Wei2004], docs/fluid.md), as LBL_HOSTDEV
// functions over plain pointers and values (GasView), as lattice/collide.h and
// backends/cuda/lb_device.h are for the lighting: the OpenMP loops of gas_solver.cpp call them
// (vectorised across a row's nodes; stream_node's interior cases there as shifted row copies,
// the same values), and a GPU kernel runs one thread per node of the same. A step is four
// launches over all nodes: collide_node, then stream_node for the flow, the temperature and the smoke. Every node writes
// only its own entries, so any order of nodes gives the same bits
// (tests/fluid/test_gas_emulated.cpp runs them launch by launch in another order).
#pragma once

#include <cstddef>
#include <cstdint>

#include "lblight/core/hostdev.h"
#include "lblight/fluid/bgk.h"

namespace lblight::fluid {

enum class FaceType { Periodic, Wall, Open };

// The three lattices a step streams.
enum GasLattice { kFlowLattice = 0, kTemperatureLattice = 1, kSmokeLattice = 2 };

// Sizes, settings and the device's arrays. Populations are [m * n + node], x fastest.
struct GasView {
  int nx = 0, ny = 0, nz = 0;
  std::size_t n = 0;
  double tau = 0.6, tau_temperature = 0.6, tau_smoke = 0.52;
  double force[3] = {0, 0, 0};
  double buoyancy = 0, t_ambient = 0;
  FaceType faces[6] = {};  // -x +x -y +y -z +z
  const std::uint8_t* solid = nullptr;  // per node
  bool any_solid = false;
  // The inlet patch in the floor: [x0, x1] x [y0, y1], where mask (nx x ny, nullptr: all) is set.
  bool inlet = false;
  int inlet_x0 = 0, inlet_x1 = -1, inlet_y0 = 0, inlet_y1 = -1;
  const std::uint8_t* inlet_mask = nullptr;
  double inlet_speed = 0, inlet_temperature = 0, inlet_smoke = 0;
  // populations at the start of the step, and after the collision
  const float *f = nullptr, *t = nullptr, *c = nullptr;
  float *f_post = nullptr, *t_post = nullptr, *c_post = nullptr;
  // per node, written by the collision: density, velocity (Guo: with half the force), scalars
  double *rho = nullptr, *ux = nullptr, *uy = nullptr, *uz = nullptr, *temperature = nullptr, *smoke = nullptr;
};

LBL_HOSTDEV inline std::size_t node_index(const GasView& v, int x, int y, int z) {
  return static_cast<std::size_t>(x) + static_cast<std::size_t>(v.nx) * (y + static_cast<std::size_t>(v.ny) * z);
}

template <int Q>
LBL_HOSTDEV inline double scalar_sum(const float* g, std::size_t n, std::size_t i) {
  double s = 0;
  LBL_UNROLL
  for (int k = 0; k < Q; ++k) s += g[k * n + i];
  return s;
}

// Collides fluid node i (flow, then temperature and smoke with the flow's velocity) into the
// post arrays and stores its moments.
LBL_HOSTDEV LBL_FORCEINLINE void collide_fluid_node(const GasView& v, std::size_t i) {
  const double temp = scalar_sum<kQ7>(v.t, v.n, i);
  v.temperature[i] = temp;
  v.smoke[i] = scalar_sum<kQ7>(v.c, v.n, i);
  // buoyancy: [Wei2004] eq. (16), upward, proportional to T - T_ambient
  const double fz = v.force[2] + v.buoyancy * (temp - v.t_ambient);
  float f[d3q19::kQ];
  LBL_UNROLL
  for (int m = 0; m < d3q19::kQ; ++m) f[m] = v.f[m * v.n + i];
  const Moments mo = collide(f, v.tau, v.force[0], v.force[1], fz);
  LBL_UNROLL
  for (int m = 0; m < d3q19::kQ; ++m) v.f_post[m * v.n + i] = f[m];
  v.rho[i] = mo.rho;
  v.ux[i] = mo.ux;
  v.uy[i] = mo.uy;
  v.uz[i] = mo.uz;
  float g[kQ7];
  LBL_UNROLL
  for (int k = 0; k < kQ7; ++k) g[k] = v.t[k * v.n + i];
  collide_scalar(g, v.tau_temperature, mo.ux, mo.uy, mo.uz);
  LBL_UNROLL
  for (int k = 0; k < kQ7; ++k) v.t_post[k * v.n + i] = g[k];
  LBL_UNROLL
  for (int k = 0; k < kQ7; ++k) g[k] = v.c[k * v.n + i];
  collide_scalar(g, v.tau_smoke, mo.ux, mo.uy, mo.uz);
  LBL_UNROLL
  for (int k = 0; k < kQ7; ++k) v.c_post[k * v.n + i] = g[k];
}

// The same for any node: solid nodes are left alone.
LBL_HOSTDEV inline void collide_node(const GasView& v, std::size_t i) {
  if (!v.solid[i]) collide_fluid_node(v, i);
}

// Pull streaming into node (x, y, z) of one lattice (Q = 19 for the flow, 7 for a scalar): value
// m comes from x - e_m. Across a periodic face it wraps; from a wall face or an obstacle it is the
// node's own opposite value bounced back half-way (no flux through either); from an open face
// the equilibrium at ambient pressure (an outlet); from the inlet patch below the floor, the
// inflow's equilibrium. `post` and `next` are that lattice's arrays.
template <int Q>
LBL_HOSTDEV inline void stream_node(const GasView& v, GasLattice lattice, const float* post, float* next, int x, int y,
                                    int z) {
  const std::size_t i = node_index(v, x, y, z);
  if (v.solid[i]) return;
  const std::size_t n = v.n;
  // Interior nodes of an obstacle-free box: every source is a plain neighbour.
  if (!v.any_solid && x > 0 && y > 0 && z > 0 && x < v.nx - 1 && y < v.ny - 1 && z < v.nz - 1) {
    for (int m = 0; m < Q; ++m)
      next[m * n + i] = post[m * n + node_index(v, x - d3q19::cx(m), y - d3q19::cy(m), z - d3q19::cz(m))];
    return;
  }
  const int size[3] = {v.nx, v.ny, v.nz};
  const double scalar_in = lattice == kTemperatureLattice ? v.inlet_temperature : v.inlet_smoke;
  const bool over_inlet = v.inlet && x >= v.inlet_x0 && x <= v.inlet_x1 && y >= v.inlet_y0 && y <= v.inlet_y1 &&
                          (!v.inlet_mask || v.inlet_mask[static_cast<std::size_t>(y) * v.nx + x]);
  for (int m = 0; m < Q; ++m) {
    int p[3] = {x - d3q19::cx(m), y - d3q19::cy(m), z - d3q19::cz(m)};
    int leaving = -1;  // the face (0..5) the source lies beyond
    for (int a = 0; a < 3 && leaving < 0; ++a) {
      if (p[a] >= 0 && p[a] < size[a]) continue;
      const int face = 2 * a + (p[a] < 0 ? 0 : 1);
      if (v.faces[face] == FaceType::Periodic) p[a] = (p[a] + size[a]) % size[a];
      else leaving = face;
    }
    float value;
    if (leaving == 4 && over_inlet) {
      value = lattice == kFlowLattice ? static_cast<float>(equilibrium<double>(m, 1.0, 0.0, 0.0, v.inlet_speed))
                                      : static_cast<float>(scalar_equilibrium(m, scalar_in, 0.0, 0.0, v.inlet_speed));
    } else if (leaving >= 0) {
      if (v.faces[leaving] == FaceType::Open) {
        // An outlet held at the ambient pressure: what enters is the equilibrium of density 1 and
        // the node's own velocity (scalar: its own value). With the node's own density instead,
        // air drawn in through a side face ran away (measured: Mach 1.3 by step 600).
        const double own = lattice == kTemperatureLattice ? v.temperature[i] : v.smoke[i];
        value = lattice == kFlowLattice ? static_cast<float>(equilibrium<double>(m, 1.0, v.ux[i], v.uy[i], v.uz[i]))
                                        : static_cast<float>(scalar_equilibrium(m, own, v.ux[i], v.uy[i], v.uz[i]));
      } else {
        value = post[static_cast<std::size_t>(d3q19::opposite(m)) * n + i];
      }
    } else {
      const std::size_t src = node_index(v, p[0], p[1], p[2]);
      value = v.solid[src] ? post[static_cast<std::size_t>(d3q19::opposite(m)) * n + i] : post[m * n + src];
    }
    next[m * n + i] = value;
  }
}

}  // namespace lblight::fluid
