// The gas solver ([Wei2004] secs. 3-5, docs/fluid.md): D3Q19 BGK flow on a box of nodes with
// obstacles (bounce-back), box faces that are periodic, walls or open outlets, a velocity inlet
// patch on the floor, a body force, and the buoyancy of temperature, which two D3Q7 lattices
// advect and diffuse with smoke. CPU loop (OpenMP) around the per-node update of fluid/gas_node.h
// (node rules: fluid/bgk.h).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "lblight/fluid/gas_node.h"
#include "lblight/lattice/lattice.h"

namespace lblight::fluid {

// DRAM bytes one node update moves (for `lblight bench --gas`): the collision reads 19 + 7 + 7
// floats and writes as many post-collision values plus 6 doubles (rho, u, temperature, smoke);
// streaming reads the 33 post-collision floats and writes 33; the obstacle byte twice.
inline constexpr int kGasBytesPerUpdate = 4 * 33 * 4 + 6 * 8 + 2;
// Memory per node: two copies of 33 floats, 6 doubles, the obstacle byte.
inline constexpr int kGasBytesPerNode = 2 * 33 * 4 + 6 * 8 + 1;

// A velocity inlet on the floor (the -z face): fluid enters the box through the patch
// [x0, x1] x [y0, y1] (node indices, inclusive) at speed `speed` upward, with temperature
// and smoke concentration.
struct Inlet {
  bool enabled = false;
  int x0 = 0, x1 = -1, y0 = 0, y1 = -1;
  std::vector<std::uint8_t> mask;  // nx x ny floor nodes inside the patch that blow (empty: all of it)
  double speed = 0.05, temperature = 0, smoke = 1;
};

struct GasSettings {
  Dims dims{8, 8, 8};
  double tau = 0.6;                       // flow relaxation time: nu = (tau - 1/2) / 3
  std::array<double, 3> force{0, 0, 0};   // uniform body force per node
  double buoyancy = 0;                    // H g of eq. (16): upward force per unit T - t_ambient
  double t_ambient = 0;
  double tau_temperature = 0.6;           // diffusivity (tau - 1/2) / 4
  double tau_smoke = 0.52;
  std::array<FaceType, 6> faces{FaceType::Periodic, FaceType::Periodic, FaceType::Periodic,
                                FaceType::Periodic, FaceType::Periodic, FaceType::Periodic};  // -x +x -y +y -z +z
  std::vector<std::uint8_t> solid;        // per node (empty: none): obstacle, bounce-back
  Inlet inlet;
  int threads = 0;                        // 0 = all cores; results do not depend on it
};

// The stability and accuracy rules, checked before anything runs: tau at least 0.503
// (nu >= 1e-3: a smaller one lets the populations go negative), scalar taus likewise, the inlet's
// Mach number (speed sqrt(3)) at most 0.3 (BGK is a low-Mach model), sizes and masks consistent.
// Returns an empty string when the settings are fine, else what is wrong and what is allowed.
std::string check_gas_settings(const GasSettings& settings);

// The settings part of the node functions' view (sizes, relaxation, forces, faces, obstacles,
// inlet); the caller adds its arrays. It points into `settings` (an empty obstacle mask: none, so
// give GasSolver's own settings() or a mask of every node).
GasView settings_view(const GasSettings& settings);

class GasSolver {
 public:
  // Error(InvalidInput) with check_gas_settings' message when the settings are refused. Starts
  // at rest (rho 1, u 0), temperature t_ambient, no smoke.
  explicit GasSolver(const GasSettings& settings);

  void step(int steps = 1);
  long long steps_done() const { return steps_; }

  // Node state as equilibria: rho, u and scalars per node (size dims.count(); empty = unchanged).
  void set_state(const std::vector<double>& rho, const std::array<std::vector<double>, 3>& u,
                 const std::vector<double>& temperature, const std::vector<double>& smoke);

  // Macroscopic fields of the last step (u as in Guo's scheme, with half the force).
  std::vector<double> density() const;
  std::array<std::vector<double>, 3> velocity() const;
  std::vector<double> temperature() const;
  std::vector<double> smoke() const;
  // The fastest node of the last step: its speed |u| (1e300 for a non-finite one) and index.
  std::pair<double, std::size_t> fastest_node() const;
  double total_mass() const;
  std::array<double, 3> total_momentum() const;  // sum of f e over fluid nodes (no force half-step)

  const GasSettings& settings() const { return s_; }

 private:
  GasView view();  // this solver's arrays and settings, for the node functions
  template <int Q>
  void stream(GasLattice lattice, const float* post, float* next);
  void collide_all();
  double scalar(const std::vector<float>& g, std::size_t i) const;

  GasSettings s_;
  std::size_t n_ = 0;
  std::vector<float> f_, f_post_, t_, t_post_, c_, c_post_;  // [m * n + node]
  std::vector<double> rho_, ux_, uy_, uz_, temp_, smoke_;  // per node, as of the last collision
  // Per row (row_of), from the obstacles: rows holding a solid node collide run by run between
  // them; rows whose 3 x 3 neighbourhood of rows is fluid stream by plain shifted copies (the
  // others inside the box with selects for the obstacles).
  std::size_t row_of(int y, int z) const { return static_cast<std::size_t>(y) + static_cast<std::size_t>(s_.dims.ny) * z; }
  std::vector<std::uint8_t> row_has_solid_, row_streams_plainly_;
  long long steps_ = 0;
  int threads_ = 1;
};

}  // namespace lblight::fluid
