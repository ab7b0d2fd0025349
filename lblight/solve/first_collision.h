// The calibrated model's first_collision correction (docs/model.md sec. 8), for the ambient
// solution B00: light that has not scattered yet is known exactly (transmittance along its path),
// so B00 stores that exact uncollided fluence, averaged over each voxel as physical fluence is,
// and the lattice solves only the light scattered from it, fed by its first collisions as a volume
// source. The lattice's own B00 carries isotropic light along 18 beams: in a pure absorber that is
// 14-20% off (the shadows of each clump fall along 18 lines only); the exact field is marched
// along many directions. A beam along a lattice direction has no such error, so B01..B18 stay as
// the lattice solves them.
#pragma once

#include <array>
#include <vector>

#include "lblight/backend/backend.h"
#include "lblight/core/run_context.h"
#include "lblight/lattice/lb_model.h"

namespace lblight {

// The physical light a base solution's boundary stands for (docs/truth.md sec. 2): beams (unit
// travel direction, fluence) and isotropic light of a fluence.
struct UncollidedLight {
  std::vector<std::pair<std::array<double, 3>, double>> beams;
  double isotropic_fluence = 0;
};
UncollidedLight base_solution_uncollided(int index);  // B_j: a unit beam along n_j; B00: isotropic, 18

// Directions over the sphere (equal weights) that isotropic light is marched along.
inline constexpr int kUncollidedDirections = 128;

// The extinction per material that light is attenuated by under `model` (delta-M scaled where
// that correction is on: lb_model.h, model_params).
std::array<double, kMaxMaterials> model_extinction(const std::array<OpticalParams, kMaxMaterials>& optics,
                                                   const LbModel& model);

// The light the uncollided beams of `boundary` scatter at their first collision, as the source
// of a lattice solve of the scattered light alone (boundary values 0; solve/krylov.h with the
// source as b). It comes from the lattice's own 18 beams, not from the exact field (whose
// directions are not the lattice's): they run along the lattice directions the boundary feeds
// (f_j of `boundary`), with exact transmittance exp(-rho sigma_t |c_j|) per node crossed; a node scatters the exact
// first-collision share 1 - exp(-rho sigma_t |c_j|) of what enters it (the lattice's own rule,
// rho r_j, is first order in rho), spread over the directions as the material's Omega column j.
struct FirstCollisionSource {
  std::vector<double> state;   // 19 x count, direction-major (StateAccess): arriving at step start
  // Per node, half of what scattered there into the moving directions (the voxel average's share;
  // 0 where the material's voxel_average is off). Nothing scatters into f_0: first_collision
  // needs remove_absorbed, which empties Omega's row 0.
  std::vector<double> credit;
};
FirstCollisionSource first_collision_source(const LatticeGeometry& lattice,
                                            const std::array<OpticalParams, kMaxMaterials>& optics,
                                            const LbModel& model, const ChannelMaterials& channel,
                                            const std::array<double, 19>& boundary);

// The exact uncollided fluence, voxel-averaged, of each channel (sigma_t[c][material], delta-M
// scaled where the model scales it) from one set of voxel walks.
std::vector<std::vector<double>> exact_uncollided(const LatticeGeometry& lattice,
                                                   const std::vector<std::array<double, kMaxMaterials>>& sigma_t,
                                                   const UncollidedLight& light, int directions = kUncollidedDirections,
                                                   const RunContext& ctx = {});
// One channel.
std::vector<double> exact_uncollided(const LatticeGeometry& lattice, const std::array<double, kMaxMaterials>& sigma_t,
                                     const UncollidedLight& light, int directions = kUncollidedDirections);

}  // namespace lblight
