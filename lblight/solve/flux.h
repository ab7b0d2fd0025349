// The first angular moment of the light (docs/model.md sec. 3.2): the flux vector
// J = sum_m f_m n_m of each node, what a renderer needs besides the scalar light to in-scatter with
// the material's phase function to first order (P1, docs/rendering.md sec. 1). n_m is the unit
// vector of direction m, so a beam of fluence phi along n_j has J = phi n_j.
#pragma once

#include <array>
#include <vector>

#include "lblight/backend/backend.h"

namespace lblight {

// Per axis (x, y, z), one value per lattice node.
using FluxField = std::array<std::vector<float>, 3>;

// The flux of one system's state (StateAccess::read_state: 19 x nodes, direction-major, the light
// arriving at each node). Where the material's totals are voxel averages (the calibrated model),
// the flux is one too: the mean of the arriving flux and the flux leaving after the collision,
// J + rho/2 sum_m n_m (Omega f~)_m with f~_0 = 0 where the material absorbs, as the scalar total
// is the mean of what enters and leaves (collision_op.h, total_gain). Ground nodes keep the
// arriving flux.
FluxField state_flux(const LatticeGeometry& lattice, const ChannelMaterials& channel, const std::vector<double>& state);

}  // namespace lblight
