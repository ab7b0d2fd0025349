#include "lblight/solve/first_collision.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <omp.h>

#include "lblight/lattice/d3q19.h"

namespace lblight {

namespace {

using namespace d3q19;

constexpr int kPointsPerBeam = 16;

// The path from point (x, y, z) + offset (offset within the node's voxel, [-1/2, 1/2) per axis)
// back against `travel` to the surface of the interior voxels' box [1/2, n - 3/2], where the
// reference's light enters (docs/truth.md sec. 1), as density x length per material: every
// channel's optical depth from one voxel walk (Amanatides and Woo; exact for the
// piecewise-constant medium). Stops once `floor` . length passes 40 (exp(-40): nothing arrives).
using Lengths = std::array<double, kMaxMaterials>;
Lengths path_to_surface(const LatticeGeometry& g, int x, int y, int z, const std::array<double, 3>& offset,
                        const std::array<double, 3>& travel, const Lengths& floor) {
  const Dims& d = g.dims;
  const int hi[3] = {d.nx - 2, d.ny - 2, d.nz - 2};
  int v[3] = {x, y, z}, step[3];
  double next[3], delta[3];
  for (int k = 0; k < 3; ++k) {
    const double dir = -travel[static_cast<std::size_t>(k)], o = offset[static_cast<std::size_t>(k)];
    step[k] = dir > 0 ? 1 : -1;
    delta[k] = dir != 0 ? 1.0 / std::abs(dir) : std::numeric_limits<double>::infinity();
    next[k] = dir != 0 ? (dir > 0 ? 0.5 - o : 0.5 + o) * delta[k] : delta[k];
  }
  Lengths len{};
  double t = 0, least = 0;
  for (;;) {
    const int k = next[0] <= next[1] ? (next[0] <= next[2] ? 0 : 2) : (next[1] <= next[2] ? 1 : 2);
    const std::size_t i = d.index(v[0], v[1], v[2]);
    const double add = g.density[i] * (next[k] - t);
    len[g.material[i]] += add;
    least += floor[g.material[i]] * add;
    if (least > 40.0) return len;
    t = next[k];
    next[k] += delta[k];
    v[k] += step[k];
    if (v[k] < 1 || v[k] > hi[k]) return len;
  }
}

// Point k of the R3 low-discrepancy sequence (Roberts) in the voxel, offsets in [-1/2, 1/2):
// spread evenly jointly with the isotropic light's directions (direction k from point k).
std::array<double, 3> r3_point(int k) {
  constexpr double g = 1.2207440846057596;  // the positive root of x^4 = x + 1
  const double a[3] = {1.0 / g, 1.0 / (g * g), 1.0 / (g * g * g)};
  std::array<double, 3> p{};
  for (int i = 0; i < 3; ++i) {
    const double v = 0.5 + a[i] * (k + 1);
    p[static_cast<std::size_t>(i)] = v - std::floor(v) - 0.5;
  }
  return p;
}

// Point k of `count` points of the voxel (offsets in [-1/2, 1/2) per axis) for a beam: on each
// axis the points are the midpoints of `count` equal strata, in an order of their own per axis (a
// Latin hypercube: multipliers prime to count), so the mean along an axis is the midpoint rule's
// (R3's first 16 points are 0.75% off there).
std::array<double, 3> voxel_point(int k, int count) {
  static constexpr int kMultipliers[] = {7, 11, 13, 17, 19, 23, 29, 31};
  std::array<double, 3> p{};
  int axis = 0;
  for (int a : kMultipliers) {
    if (axis == 3) break;
    if (std::gcd(a, count) != 1) continue;
    const int stratum = static_cast<int>((static_cast<long long>(a) * k + 3 * axis + 1) % count);
    p[static_cast<std::size_t>(axis++)] = (stratum + 0.5) / count - 0.5;
  }
  return p;
}

// Visits every interior node (x, y, z) after its upstream neighbour (x, y, z) - c, which it is
// given as (px, py, pz): the order in which a lattice direction's light crosses the lattice.
template <typename F>
void sweep_along(const Dims& d, const int c[3], F&& visit) {
  auto range = [](int c, int n, int& from, int& to, int& by) {
    from = c >= 0 ? 1 : n - 2, to = c >= 0 ? n - 1 : 0, by = c >= 0 ? 1 : -1;
  };
  int z0, z1, dz, y0, y1, dy, x0, x1, dx;
  range(c[2], d.nz, z0, z1, dz);
  range(c[1], d.ny, y0, y1, dy);
  range(c[0], d.nx, x0, x1, dx);
  for (int z = z0; z != z1; z += dz)
    for (int y = y0; y != y1; y += dy)
      for (int x = x0; x != x1; x += dx) visit(x, y, z, x - c[0], y - c[1], z - c[2]);
}

// A direction light arrives from, its share of the fluence, and how many points of a voxel it is
// averaged over.
struct Ray {
  std::array<double, 3> travel;
  double fluence;
  int points;
};

// The light's beams (at kPointsPerBeam points of a voxel each) and its isotropic part as
// `directions` directions of a spherical Fibonacci set (near-uniform, equal weights), each from
// its own point of the voxel (r3_point; a beam's points: voxel_point).
std::vector<Ray> all_rays(const UncollidedLight& light, int directions) {
  std::vector<Ray> rays;
  for (const auto& b : light.beams) rays.push_back({b.first, b.second, kPointsPerBeam});
  if (light.isotropic_fluence != 0) {
    const double golden = M_PI * (3.0 - std::sqrt(5.0));
    for (int k = 0; k < directions; ++k) {
      const double z = 1.0 - (2.0 * k + 1.0) / directions, r = std::sqrt(std::max(0.0, 1.0 - z * z));
      const std::array<double, 3> travel{r * std::cos(golden * k), r * std::sin(golden * k), z};
      rays.push_back({travel, light.isotropic_fluence / directions, 1});
    }
  }
  return rays;
}

}  // namespace

UncollidedLight base_solution_uncollided(int index) {
  UncollidedLight l;
  if (index == 0) {
    l.isotropic_fluence = 18.0;
  } else {
    const double len = std::sqrt(static_cast<double>(length_sq(index)));
    l.beams.push_back({{cx(index) / len, cy(index) / len, cz(index) / len}, 1.0});
  }
  return l;
}

std::vector<std::vector<double>> exact_uncollided(const LatticeGeometry& g,
                                                   const std::vector<std::array<double, kMaxMaterials>>& sigma_t,
                                                   const UncollidedLight& light, int directions,
                                                   const RunContext& ctx) {
  const Dims& d = g.dims;
  const std::size_t channels = sigma_t.size();
  Lengths floor{};
  for (std::size_t m = 0; m < floor.size(); ++m) {
    floor[m] = std::numeric_limits<double>::infinity();
    for (const auto& s : sigma_t) floor[m] = std::min(floor[m], s[m]);
  }
  const std::vector<Ray> rays = all_rays(light, directions);
  std::vector<std::vector<double>> phi(channels, std::vector<double>(d.count(), 0.0));
  const int threads = ctx.threads > 0 ? ctx.threads : omp_get_max_threads();
#pragma omp parallel for schedule(dynamic) num_threads(threads)
  for (int z = 1; z < d.nz - 1; ++z) {
    if (ctx.cancelled()) continue;  // a large lattice walks for a while (docs/model.md sec. 8)
    std::vector<double> v(channels), sum(channels);
    for (int y = 1; y < d.ny - 1; ++y)
      for (int x = 1; x < d.nx - 1; ++x) {
        // the voxel's mean, over the rays' points
        std::fill(v.begin(), v.end(), 0.0);
        int iso = 0;
        for (const Ray& ray : rays) {
          std::fill(sum.begin(), sum.end(), 0.0);
          for (int k = 0; k < ray.points; ++k) {
            const std::array<double, 3> at = ray.points > 1 ? voxel_point(k, ray.points) : r3_point(iso++);
            const Lengths len = path_to_surface(g, x, y, z, at, ray.travel, floor);
            for (std::size_t c = 0; c < channels; ++c) {
              double tau = 0;
              for (std::size_t m = 0; m < len.size(); ++m) tau += sigma_t[c][m] * len[m];
              sum[c] += std::exp(-tau);
            }
          }
          for (std::size_t c = 0; c < channels; ++c) v[c] += ray.fluence * sum[c] / ray.points;
        }
        for (std::size_t c = 0; c < channels; ++c) phi[c][d.index(x, y, z)] = v[c];
      }
  }
  ctx.check_cancelled();
  return phi;
}

std::vector<double> exact_uncollided(const LatticeGeometry& g, const std::array<double, kMaxMaterials>& sigma_t,
                                     const UncollidedLight& light, int directions) {
  const std::vector<std::array<double, kMaxMaterials>> one{sigma_t};
  return std::move(exact_uncollided(g, one, light, directions, {})[0]);
}

std::array<double, kMaxMaterials> model_extinction(const std::array<OpticalParams, kMaxMaterials>& optics,
                                                   const LbModel& model) {
  std::array<double, kMaxMaterials> sigma_t{};
  for (std::size_t m = 0; m < sigma_t.size(); ++m) sigma_t[m] = model_params(optics[m], model).sigma_t();
  return sigma_t;
}

FirstCollisionSource first_collision_source(const LatticeGeometry& g,
                                            const std::array<OpticalParams, kMaxMaterials>& optics,
                                            const LbModel& model, const ChannelMaterials& channel,
                                            const std::array<double, 19>& boundary) {
  const Dims& d = g.dims;
  const std::size_t n = d.count();
  const std::array<double, kMaxMaterials> sigma_t = model_extinction(optics, model);
  std::array<std::array<double, kQ>, kMaxMaterials> removed{};
  for (std::size_t m = 0; m < removed.size(); ++m) removed[m] = model_removal(optics[m], model);
  FirstCollisionSource out;
  out.state.assign(kQ * n, 0.0);
  out.credit.assign(n, 0.0);
  std::vector<double> u(n);
  for (int j = 1; j < kQ; ++j) {
    const double b = boundary[static_cast<std::size_t>(j)];
    if (b == 0) continue;
    const int c[3] = {cx(j), cy(j), cz(j)};
    const double len = std::sqrt(static_cast<double>(length_sq(j)));
    sweep_along(d, c, [&](int x, int y, int z, int px, int py, int pz) {
      const std::size_t p = d.index(px, py, pz);
      const double crossed = std::exp(-g.density[p] * sigma_t[g.material[p]] * len);
      u[d.index(x, y, z)] = d.is_boundary(px, py, pz) ? b : u[p] * crossed;
    });
    for (int z = 1; z < d.nz - 1; ++z)
      for (int y = 1; y < d.ny - 1; ++y)
        for (int x = 1; x < d.nx - 1; ++x) {
          const std::size_t q = d.index(x, y, z);
          const double rho = g.density[q];
          const int mat = g.material[q];
          const double r = removed[static_cast<std::size_t>(mat)][static_cast<std::size_t>(j)];
          if (!(rho > 0) || !(r > 0)) continue;
          // rho r_j of the entering light leaves j in the lattice's collision; the exact share
          // is -expm1(-rho sigma_t |c_j|): Omega's column j scaled to it
          const double a = -std::expm1(-rho * sigma_t[static_cast<std::size_t>(mat)] * len) / r * u[q];
          const OmegaMatrix& om = channel.omega[static_cast<std::size_t>(mat)];
          for (int m = 0; m < kQ; ++m) {
            const double v = a * (om[static_cast<std::size_t>(m * kQ + j)] + (m == j ? r : 0.0));
            if (m == 0) {
              out.state[q] += v;  // the rest component stays at the node
              continue;
            }
            if (channel.voxel_average[static_cast<std::size_t>(mat)]) out.credit[q] += 0.5 * v;
            const int tx = x + cx(m), ty = y + cy(m), tz = z + cz(m);
            if (!d.is_boundary(tx, ty, tz)) out.state[static_cast<std::size_t>(m) * n + d.index(tx, ty, tz)] += v;
          }
        }
  }
  return out;
}

}  // namespace lblight
