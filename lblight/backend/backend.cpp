#include "lblight/backend/backend.h"

#include <cmath>
#include <stdexcept>

#include "lblight/core/error.h"

namespace lblight {

std::string supported_precisions(const Backend& backend) {
  std::string out;
  for (Precision p : {Precision::Float32, Precision::Float64, Precision::Float16})
    if (backend.supports(p)) out += (out.empty() ? "" : ", ") + std::string(to_string(p));
  return out;
}

void check_geometry(const LatticeGeometry& g, const char* backend) {
  const auto fail = [&](const std::string& what) {
    throw std::logic_error(std::string(backend) + " backend: lattice geometry " + what);
  };
  const Dims& d = g.dims;
  // an input the caller can meet (a tiny model), not a broken contract: InvalidInput
  if (d.nx < 3 || d.ny < 3 || d.nz < 3) throw_invalid("lattice must have at least 3 nodes per edge");
  if (g.density.size() != d.count() || g.material.size() != d.count())
    fail("has " + std::to_string(g.density.size()) + " densities and " + std::to_string(g.material.size()) +
         " materials for " + std::to_string(d.count()) + " nodes");
  if (g.material_count < 1 || g.material_count > kMaxMaterials)
    fail("has material_count " + std::to_string(g.material_count) + ", allowed 1.." + std::to_string(kMaxMaterials));
  for (int z = 0; z < d.nz; ++z)
    for (int y = 0; y < d.ny; ++y)
      for (int x = 0; x < d.nx; ++x) {
        const std::size_t i = d.index(x, y, z);
        const auto at = [&] {
          return " at node (" + std::to_string(x) + ", " + std::to_string(y) + ", " + std::to_string(z) + ")";
        };
        if (g.material[i] >= g.material_count)
          fail("has material " + std::to_string(g.material[i]) + at() + ", allowed below " +
               std::to_string(g.material_count));
        const float rho = g.density[i];
        if (!std::isfinite(rho) || rho < 0.0f) fail("has density " + std::to_string(rho) + at());
        if (rho != 0.0f && d.is_boundary(x, y, z)) fail("has density " + std::to_string(rho) + " on the boundary" + at());
        if (g.material[i] == kMaterialGround && !d.is_boundary(x, y, z) &&
            g.material[d.index(1, y, z)] != kMaterialGround)
          fail("has a ground node in a row that is not all ground" + at());
        if (g.material[i] != kMaterialGround && !d.is_boundary(x, y, z) && g.material[d.index(1, y, z)] == kMaterialGround)
          fail("has a node of material " + std::to_string(g.material[i]) + " in a row of ground" + at());
      }
}

bool LatticeGeometry::has_material(std::uint8_t k) const {
  for (std::size_t i = 0; i < material.size(); ++i)
    if (material[i] == k && density[i] > 0.0f) return true;
  return false;
}

std::vector<float> LatticeGeometry::medium_density() const {
  std::vector<float> d = density;
  for (std::size_t i = 0; i < d.size(); ++i)
    if (material[i] == kMaterialGround) d[i] = 0.0f;
  return d;
}

}  // namespace lblight

namespace lblight {

CollisionOp<double> channel_op(const ChannelMaterials& channel, int material) {
  const auto k = static_cast<std::size_t>(material);
  CollisionOp<double> op = reduce_omega(channel.omega[k], channel.voxel_average[k]);
  // The ground keeps the even/odd form even where it is cubic (albedo 0: Omega = -1): there it
  // stops light exactly, so a black ground leaves the lattice above it as bare as no ground, bit
  // for bit; the symmetry-adapted coordinates would leave rounding residues.
  if (material == kMaterialGround) op.is_cubic = 0;
  return op;
}

void StateAccess::add_mode(int system, const std::vector<double>& phi, const ModeShapes& shape,
                           const std::vector<std::uint8_t>& material) {
  std::vector<double> f;
  read_state(system, f);
  const std::size_t n = phi.size();
  if (f.size() != 19 * n || material.size() != n) throw std::invalid_argument("add_mode: wrong sizes");
  for (int m = 0; m < 19; ++m)
    for (std::size_t i = 0; i < n; ++i) f[static_cast<std::size_t>(m) * n + i] += shape[material[i]][m] * phi[i];
  write_state(system, f);
}

}  // namespace lblight
