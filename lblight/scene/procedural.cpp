#include "lblight/core/system_info.h"
#include "lblight/scene/procedural.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace lblight {
namespace {

// splitmix64: a tiny, well-mixed, platform-independent hash (std distributions are not).
std::uint64_t mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}
double unit(std::uint64_t h) { return static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0); }

class Rng {
 public:
  explicit Rng(std::uint64_t seed) : s_(mix(seed)) {}
  double next() { return unit(s_ = mix(s_)); }                 // [0, 1)
  double range(double lo, double hi) { return lo + (hi - lo) * next(); }
 private:
  std::uint64_t s_;
};

// Value noise on the integer lattice, smoothly interpolated, in [0, 1].
double value_noise(double x, double y, double z, std::uint64_t seed) {
  const double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
  const auto ix = static_cast<long long>(fx), iy = static_cast<long long>(fy), iz = static_cast<long long>(fz);
  auto smooth = [](double t) { return t * t * (3.0 - 2.0 * t); };
  const double tx = smooth(x - fx), ty = smooth(y - fy), tz = smooth(z - fz);
  auto corner = [&](long long a, long long b, long long c) {
    std::uint64_t h = mix(seed ^ mix(static_cast<std::uint64_t>(a) * 73856093ull ^
                                     mix(static_cast<std::uint64_t>(b) * 19349663ull ^
                                         mix(static_cast<std::uint64_t>(c) * 83492791ull))));
    return unit(h);
  };
  double v = 0;
  for (int dz = 0; dz < 2; ++dz)
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 2; ++dx)
        v += corner(ix + dx, iy + dy, iz + dz) * (dx ? tx : 1 - tx) * (dy ? ty : 1 - ty) * (dz ? tz : 1 - tz);
  return v;
}

double fbm(double x, double y, double z, std::uint64_t seed, int octaves) {
  double sum = 0, amp = 0.5, norm = 0, f = 1;
  for (int o = 0; o < octaves; ++o) {
    sum += amp * value_noise(x * f, y * f, z * f, seed + static_cast<std::uint64_t>(o) * 1013);
    norm += amp;
    amp *= 0.5;
    f *= 2.03;
  }
  return sum / norm;
}


ModelGrid make_cloud(const ProceduralSource& s, const RunContext& ctx) {
  const int r = s.resolution;
  ModelGrid g;
  g.dims = {r, std::max(4, static_cast<int>(std::lround(0.75 * r))), std::max(4, static_cast<int>(std::lround(0.55 * r)))};
  const double h = s.size / r;
  g.index_to_world = centred_transform(g.dims, h, false);
  g.density.assign(g.dims.count(), 0.0f);
  g.material.assign(g.dims.count(), kMaterialMedium);
  const double cx = 0.5 * (g.dims.nx - 1), cy = 0.5 * (g.dims.ny - 1), cz = 0.5 * (g.dims.nz - 1);
  const double ax = 0.42 * g.dims.nx, ay = 0.40 * g.dims.ny, az = 0.38 * g.dims.nz;
  const double freq = 6.0 / r;
#pragma omp parallel for schedule(dynamic) num_threads(ctx.threads > 0 ? ctx.threads : omp_get_max_threads())
  for (int k = 0; k < g.dims.nz; ++k) {
    if (ctx.cancelled()) continue;
    for (int j = 0; j < g.dims.ny; ++j)
      for (int i = 0; i < g.dims.nx; ++i) {
        const double u = (i - cx) / ax, v = (j - cy) / ay;
        double w = (k - cz) / az;
        if (w < 0) w *= 1.6;  // flatter base, billowing top
        const double radius = std::sqrt(u * u + v * v + w * w);
        const double n = fbm(i * freq, j * freq, k * freq, s.seed, 4);
        const double shell = 1.0 - radius + 0.55 * (n - 0.5);
        const double d = std::clamp(shell * 3.0, 0.0, 1.0);
        g.density[g.dims.index(i, j, k)] = static_cast<float>(d);
      }
  }
  ctx.check_cancelled();
  g.description = "procedural cloud, resolution " + std::to_string(r) + ", seed " + std::to_string(s.seed);
  return g;
}

// Distance from point p to the segment a-b.
double segment_distance(const double p[3], const double a[3], const double b[3]) {
  double ab[3], ap[3];
  for (int c = 0; c < 3; ++c) {
    ab[c] = b[c] - a[c];
    ap[c] = p[c] - a[c];
  }
  const double len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
  double t = len2 > 0 ? (ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2]) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  double d2 = 0;
  for (int c = 0; c < 3; ++c) {
    const double q = ap[c] - t * ab[c];
    d2 += q * q;
  }
  return std::sqrt(d2);
}

struct Limb {
  double a[3], b[3], r0, r1;  // tapered capsule, radius r0 at a, r1 at b
};
struct Cluster {
  double c[3], radius, density;
};

ModelGrid make_plant(const ProceduralSource& s, const RunContext& ctx) {
  const int r = s.resolution;
  ModelGrid g;
  const int width = std::max(4, static_cast<int>(std::lround(0.8 * r)));
  g.dims = {width, width, r};
  const double h = s.size / r;
  g.index_to_world = centred_transform(g.dims, h, true);
  g.density.assign(g.dims.count(), 0.0f);
  g.material.assign(g.dims.count(), kMaterialMedium);

  // Geometry in units of the plant's height (z in [0, 1]), trunk on the axis x = y = 0.
  Rng rng(s.seed);
  std::vector<Limb> limbs;
  const double top = 0.55;
  limbs.push_back({{0, 0, 0}, {0, 0, top}, 0.045, 0.03});
  std::vector<Cluster> clusters;
  const int branches = 5 + static_cast<int>(rng.next() * 3);
  for (int b = 0; b < branches; ++b) {
    const double angle = 2 * 3.14159265358979 * (b + rng.range(-0.25, 0.25)) / branches;
    const double start_z = rng.range(0.30, top);
    const double reach = rng.range(0.18, 0.28);
    const double end[3] = {reach * std::cos(angle), reach * std::sin(angle), std::min(0.85, start_z + rng.range(0.15, 0.3))};
    limbs.push_back({{0, 0, start_z}, {end[0], end[1], end[2]}, 0.022, 0.012});
    clusters.push_back({{end[0], end[1], end[2]}, rng.range(0.11, 0.16), rng.range(0.25, 0.45)});
  }
  clusters.push_back({{0, 0, top + 0.2}, 0.17, 0.4});  // crown top
  const double half_x = 0.5 * (g.dims.nx - 1), half_y = 0.5 * (g.dims.ny - 1);

  // 3x3x3 samples per node give partial occupancy for wood; leaves are a noise-modulated
  // density inside each cluster (a "leaf cloud", [Geist2010] sec. 3.2.2).
  // A sample lies within sqrt(3)/3 voxel of its node's centre: a centre farther than that beyond
  // every limb's surface has no sample inside one (the same hits, without the 27 x limbs tests).
  const double reach = std::sqrt(3.0) / 3.0 / r;
#pragma omp parallel for schedule(dynamic) num_threads(ctx.threads > 0 ? ctx.threads : omp_get_max_threads())
  for (int k = 0; k < g.dims.nz; ++k) {
    if (ctx.cancelled()) continue;
    for (int j = 0; j < g.dims.ny; ++j)
      for (int i = 0; i < g.dims.nx; ++i) {
        int wood_hits = 0;
        const double centre[3] = {(i - half_x) / r, (j - half_y) / r, (k + 0.5) / r};
        bool near_limb = false;
        for (const Limb& l : limbs)
          near_limb = near_limb || segment_distance(centre, l.a, l.b) <= std::max(l.r0, l.r1) + reach;
        if (near_limb)
        for (int sz = -1; sz <= 1; ++sz)
          for (int sy = -1; sy <= 1; ++sy)
            for (int sx = -1; sx <= 1; ++sx) {
              const double p[3] = {(i - half_x + sx / 3.0) / r, (j - half_y + sy / 3.0) / r, (k + 0.5 + sz / 3.0) / r};
              for (const Limb& l : limbs) {
                double t_ab[3];
                for (int c = 0; c < 3; ++c) t_ab[c] = l.b[c] - l.a[c];
                const double d = segment_distance(p, l.a, l.b);
                const double len = std::sqrt(t_ab[0] * t_ab[0] + t_ab[1] * t_ab[1] + t_ab[2] * t_ab[2]);
                const double along = len > 0 ? std::clamp(((p[0] - l.a[0]) * t_ab[0] + (p[1] - l.a[1]) * t_ab[1] +
                                                           (p[2] - l.a[2]) * t_ab[2]) / (len * len), 0.0, 1.0)
                                             : 0.0;
                if (d <= l.r0 + (l.r1 - l.r0) * along) {
                  ++wood_hits;
                  break;
                }
              }
            }
        const double wood = wood_hits / 27.0;
        const double p[3] = {(i - half_x) / r, (j - half_y) / r, (k + 0.5) / r};
        double leaf = 0;
        for (const Cluster& c : clusters) {
          const double dx = p[0] - c.c[0], dy = p[1] - c.c[1], dz = p[2] - c.c[2];
          const double q = std::sqrt(dx * dx + dy * dy + dz * dz) / c.radius;
          if (q >= 1.0) continue;
          const double n = fbm(p[0] * 14, p[1] * 14, p[2] * 14, s.seed ^ 0x5eedull, 3);
          leaf = std::max(leaf, c.density * (1.0 - q * q) * (0.4 + 1.2 * n));
        }
        leaf = std::clamp(leaf, 0.0, 0.8);
        const std::size_t idx = g.dims.index(i, j, k);
        g.density[idx] = static_cast<float>(std::min(1.0, wood + leaf * (1.0 - wood)));
        // brown where wood occupies more of the cell than leaves ([Steele2009] sec. 4.1)
        g.material[idx] = wood > leaf * (1.0 - wood) ? kMaterialWood : kMaterialMedium;
      }
  }
  ctx.check_cancelled();
  g.description = "procedural plant, resolution " + std::to_string(r) + ", seed " + std::to_string(s.seed);
  return g;
}

// A cube of uniform density 1 (scale it with density_scale): the convergence example of docs/model.md sec. 5
// (sec. 5) and a clean test medium.
ModelGrid make_box(const ProceduralSource& s) {
  ModelGrid g;
  g.dims = {s.resolution, s.resolution, s.resolution};
  g.index_to_world = centred_transform(g.dims, s.size / s.resolution, false);
  g.density.assign(g.dims.count(), 1.0f);
  g.material.assign(g.dims.count(), kMaterialMedium);
  g.description = "procedural box, resolution " + std::to_string(s.resolution);
  return g;
}

}  // namespace

std::array<double, 16> centred_transform(const Dims& d, double h, bool on_ground) {
  // voxel centre (i, j, k) -> world; x/y centred on the origin, z centred or starting at 0
  const double ox = -0.5 * (d.nx - 1) * h, oy = -0.5 * (d.ny - 1) * h;
  const double oz = on_ground ? 0.5 * h : -0.5 * (d.nz - 1) * h;
  return {h, 0, 0, ox, 0, h, 0, oy, 0, 0, h, oz, 0, 0, 0, 1};
}

ModelGrid make_procedural(const ProceduralSource& src, const Location& where, const RunContext& ctx) {
  const double r = src.resolution;
  check_host_memory(r * r * r * 5.0, "a procedural " + src.shape + " at resolution " + std::to_string(src.resolution),
                    "lower the resolution", where);
  if (src.shape == "box") return make_box(src);
  if (src.shape == "cloud") return make_cloud(src, ctx);
  if (src.shape == "plant") return make_plant(src, ctx);
  throw std::invalid_argument("unknown procedural shape " + src.shape);
}

Dims procedural_least_occupied(const ProceduralSource& src) {
  // The shapes are defined in units of the grid (noise frequency and geometry scale with the
  // resolution): a coarse version of the same seed has the same occupied box, to a coarse voxel.
  constexpr int kCoarse = 48;
  if (src.resolution <= kCoarse) return make_procedural(src).dims;
  ProceduralSource coarse = src;
  coarse.resolution = kCoarse;
  const ModelGrid g = make_procedural(coarse);
  int lo[3] = {g.dims.nx, g.dims.ny, g.dims.nz}, hi[3] = {-1, -1, -1};
  for (int k = 0; k < g.dims.nz; ++k)
    for (int j = 0; j < g.dims.ny; ++j)
      for (int i = 0; i < g.dims.nx; ++i)
        if (g.density[g.dims.index(i, j, k)] > 0.0f) {
          const int at[3] = {i, j, k};
          for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], at[a]);
            hi[a] = std::max(hi[a], at[a]);
          }
        }
  const double scale = static_cast<double>(src.resolution) / kCoarse;
  int least[3];
  for (int a = 0; a < 3; ++a)  // one coarse voxel given away at each end
    least[a] = hi[a] < lo[a] ? 1 : std::max(1, static_cast<int>(std::floor((hi[a] - lo[a] - 1) * scale)));
  return {least[0], least[1], least[2]};
}

}  // namespace lblight
