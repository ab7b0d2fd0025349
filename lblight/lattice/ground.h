// The ground (docs/model.md sec. 4.3): a reflective lower boundary. The lattice's first interior
// layer holds ground nodes (material kMaterialGround, density 1) whose collision stops every
// moving direction and sends the light arriving from above back up, diffusely, with the albedo:
//   post_m = A u_m sum_{n: c_n,z < 0} f_n      for the 5 upward directions m (c_m,z = +1)
// u_m is the share of upward direction m in the model's own isotropic light (its ambient boundary
// restricted to the upper hemisphere, sum 1), so the reflected flux is exactly A times the
// arriving flux (every upward and downward direction crosses one layer per step). The operator is
// centrally symmetric, as every kernel needs: light arriving from below (the bottom boundary) is
// reflected downward, back into the boundary, and never reaches the medium.
#pragma once

#include <array>

#include "lblight/lattice/d3q19.h"
#include "lblight/lattice/omega.h"

namespace lblight {

LBL_HOSTDEV constexpr bool upward(int m) { return d3q19::cz(m) > 0; }
LBL_HOSTDEV constexpr bool downward(int m) { return d3q19::cz(m) < 0; }

// u_m: `ambient` (a model's B00 boundary values) on the upward directions, normalised to sum 1;
// 0 elsewhere.
std::array<double, d3q19::kQ> ground_share(const std::array<double, d3q19::kQ>& ambient);

// The ground nodes' collision matrix for albedo A in [0, 1] (used at density 1).
OmegaMatrix ground_omega(double albedo, const std::array<double, d3q19::kQ>& share);

// Boundary values of a lattice standing on an open ground: the light a source sends down
// (sum of its downward values, each crossing the ground plane once per step) comes back up from
// the ground around the lattice, diffusely, with the albedo. That reflection replaces the source's
// own upward values (the ground hides whatever shines from below), so that an empty lattice over
// the ground is uniform (the ground inside the lattice reflects exactly what its boundary brings
// in). Linear in the source, so superposition of base solutions holds.
std::array<double, d3q19::kQ> with_open_ground(const std::array<double, d3q19::kQ>& source, double albedo,
                                               const std::array<double, d3q19::kQ>& share);

}  // namespace lblight
