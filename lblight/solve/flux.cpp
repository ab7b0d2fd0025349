#include "lblight/solve/flux.h"

#include <cmath>
#include <stdexcept>

#include "lblight/lattice/d3q19.h"
#include "lblight/lattice/dense_grid.h"

namespace lblight {
namespace {

std::array<double, 3> unit_direction(int m) {
  const double len = std::sqrt(static_cast<double>(d3q19::length_sq(m)));
  return {d3q19::cx(m) / len, d3q19::cy(m) / len, d3q19::cz(m) / len};
}

}  // namespace

FluxField state_flux(const LatticeGeometry& lattice, const ChannelMaterials& channel, const std::vector<double>& state) {
  constexpr int kQ = d3q19::kQ;
  const std::size_t n = lattice.dims.count();
  if (state.size() != kQ * n) throw std::logic_error("state_flux: the state is not 19 values per node");
  std::array<std::array<double, 3>, kQ> unit{};
  for (int m = 1; m < kQ; ++m) unit[static_cast<std::size_t>(m)] = unit_direction(m);
  // Per material: the 3 x 19 matrix N^T Omega (half of it: the voxel average's share), so the
  // leaving flux's change at a node is rho times it applied to f~.
  std::array<std::array<std::array<double, kQ>, 3>, kMaxMaterials> half_change{};
  for (int k = 0; k < lattice.material_count && k < kMaxMaterials; ++k) {
    const auto kk = static_cast<std::size_t>(k);
    if (!channel.voxel_average[kk] || k == kMaterialGround) continue;
    for (int a = 0; a < 3; ++a)
      for (int col = 0; col < kQ; ++col) {
        double s = 0;
        for (int m = 1; m < kQ; ++m) s += unit[static_cast<std::size_t>(m)][a] * channel.omega[kk][m * kQ + col];
        half_change[kk][a][col] = 0.5 * s;
      }
  }
  FluxField out;
  for (auto& axis : out) axis.assign(n, 0.0f);
  for (std::size_t i = 0; i < n; ++i) {
    double f[kQ];
    for (int m = 0; m < kQ; ++m) f[m] = state[static_cast<std::size_t>(m) * n + i];
    double j[3] = {0, 0, 0};
    for (int m = 1; m < kQ; ++m)
      for (int a = 0; a < 3; ++a) j[a] += f[m] * unit[static_cast<std::size_t>(m)][a];
    const std::uint8_t k = lattice.material[i];
    const double rho = lattice.density[i];
    if (rho > 0 && k < kMaxMaterials && channel.voxel_average[k] && k != kMaterialGround) {
      if (channel.absorbs[k]) f[0] = 0;
      for (int a = 0; a < 3; ++a) {
        double s = 0;
        for (int col = 0; col < kQ; ++col) s += half_change[k][static_cast<std::size_t>(a)][col] * f[col];
        j[a] += rho * s;
      }
    }
    for (int a = 0; a < 3; ++a) out[static_cast<std::size_t>(a)][i] = static_cast<float>(j[a]);
  }
  return out;
}

}  // namespace lblight
