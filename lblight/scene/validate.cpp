#include "lblight/scene/validate.h"

#include <cmath>
#include <sstream>

#include "lblight/core/error.h"

namespace lblight {

std::string voxel_string(const ModelGrid& g, std::size_t index) {
  const std::size_t nx = static_cast<std::size_t>(g.dims.nx), ny = static_cast<std::size_t>(g.dims.ny);
  const long long i = static_cast<long long>(index % nx) + g.index_min[0];
  const long long j = static_cast<long long>((index / nx) % ny) + g.index_min[1];
  const long long k = static_cast<long long>(index / (nx * ny)) + g.index_min[2];
  return "(" + std::to_string(i) + ", " + std::to_string(j) + ", " + std::to_string(k) + ")";
}

namespace {
Location source_location(const ModelSpec& m, const Scene& scene, const ModelGrid& g, std::size_t index) {
  Location where{scene.file.string(), m.density.json_path, voxel_string(g, index)};
  return where;
}

std::string source_name(const ModelSpec& m) {
  if (m.density.type == SourceType::Vdb) return "grid '" + m.density.vdb.grid + "' of " + m.density.vdb.path.string();
  if (m.density.type == SourceType::Mesh) return "mesh " + m.density.mesh.path.string();
  if (m.density.type == SourceType::Gas) return "gas smoke";
  return "procedural " + m.density.procedural.shape;
}
}  // namespace

void check_density_values(const ModelSpec& m, const ModelGrid& g, const Scene& scene) {
  for (std::size_t i = 0; i < g.density.size(); ++i) {
    const float d = g.density[i];
    if (!std::isfinite(d))
      throw_invalid("model '" + m.name + "': " + source_name(m) + " holds " + message_number(d) +
                        "; allowed: finite densities in [0, 1]",
                    source_location(m, scene, g, i));
    if (d < 0.0f || d > 1.0f)
      throw_invalid("model '" + m.name + "': " + source_name(m) + " has density " + message_number(d) +
                        " after density_scale " + message_number(m.density.density_scale) +
                        "; allowed: 0 <= density <= 1 (lower density_scale)",
                    source_location(m, scene, g, i));
  }
}

GridStats check_stability(const ModelSpec& m, const ModelGrid& g, const Scene& scene,
                          std::vector<std::string>& warnings) {
  GridStats st;
  for (std::size_t i = 0; i < g.density.size(); ++i) {
    const float d = g.density[i];
    if (d <= 0.0f) continue;
    ++st.occupied;
    const int k = g.material[i] == kMaterialWood ? 1 : 0;
    st.wood += k;
    if (d > st.max_density[k]) {
      st.max_density[k] = d;
      st.max_index[k] = i;
    }
  }
  if (st.occupied == 0) warnings.push_back("model '" + m.name + "' has no medium: light passes through unchanged");
  for (int k = 0; k < 2; ++k) {
    if (st.max_density[k] <= 0.0f) continue;
    const Material& mat = k == 0 ? m.material : m.wood_material;
    const std::string field = k == 0 ? "/material" : "/wood_material";
    const double rho = st.max_density[k];
    for (int c = 0; c < kChannels; ++c) {
      const OpticalParams& p = mat.channel[c];
      const double rst = rho * p.sigma_t();
      const LbModel& model = scene.solver.model;
      // The calibrated model loses 1 - exp(-rho sigma_t |c|) < 1 per step: no such bound (sec. 8).
      if (rst >= 2.0 && !model.calibrated) {
        Location where{scene.file.string(), m.json_path + field, voxel_string(g, st.max_index[k])};
        throw_invalid("model '" + m.name + "', material '" + mat.name + "', channel " + kChannelNames[c] +
                          ": rho * sigma_t = " + message_number(rst) + " (rho " + message_number(rho) +
                          ", sigma_t " + message_number(p.sigma_t()) +
                          "); allowed: rho * sigma_t < 2, where the LB diffusion coefficient " +
                          "((2 / (rho sigma_t)) - 1) / (4 (1 + sigma_a)) of [Geist2010] eq. (4) stays positive",
                      where);
      }
      // rho * sigma_t < 2 is not enough with backscattering (g < 0): a uniform region of this
      // density must not amplify any pattern of directions, or the scheme diverges there.
      const OmegaMatrix omega = build_model_omega(p, model);
      const double radius = collision_spectral_radius(omega, rho, model_absorbs(mat.absorbs, model));
      if (radius > 1.0 + 1e-9) {
        Location where{scene.file.string(), m.json_path + field, voxel_string(g, st.max_index[k])};
        throw_invalid("model '" + m.name + "', material '" + mat.name + "', channel " + kChannelNames[c] +
                          ": with g = " + message_number(p.g) + " one collision at rho " + message_number(rho) +
                          " amplifies a pattern of directions by " + message_number(radius) +
                          " per step (spectral radius of 1 + rho * Omega; sigma_a " + message_number(p.sigma_a) +
                          ", sigma_s " + message_number(p.sigma_s) + ", rho * sigma_t = " + message_number(rst) +
                          "); allowed: at most 1, else the scheme diverges (lower sigma_s or the density, or raise " +
                          "g; at g = -1 this needs rho * (sigma_a + 2 sigma_s) < 2)",
                      where);
      }
      const double gain = min_diagonal_gain(omega, rho);
      if (gain < 0.0)
        warnings.push_back("model '" + m.name + "', material '" + mat.name + "', channel " + kChannelNames[c] +
                           ": 1 + rho * Omega_mm = " + message_number(gain) +
                           " < 0, so values can go negative (docs/model.md sec. 6), in transients and, with absorption, " +
                           "in the converged result (docs/stability.md)");
    }
  }
  return st;
}

}  // namespace lblight
