#include "lblight/mesh/voxelize.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "lblight/core/system_info.h"
#include "lblight/mesh/tri_box.h"

namespace lblight {
namespace {

// Fine cells are closed boxes grown by this much (in fine-cell units): a triangle that touches a
// cell counts, and a face lying on the outer border of the grid is not lost to rounding.
constexpr double kEps = 1e-9;
// Tiles are at most 64 fine cells along x so that one row of a tile is one 64-bit word.
constexpr int kTileFine = 64;

struct Prepared {
  Vec3 v[3];                 // fine-index coordinates: cell (i, j, k) is [i, i+1] x [j, j+1] x [k, k+1]
  Vec3 n;                    // (v1 - v0) x (v2 - v0)
  double d = 0;              // n . v0
  std::array<int, 3> lo{}, hi{};  // fine cells the bounding box touches, clamped to the grid
  std::uint8_t cls = 0;      // TriangleClass
  std::uint8_t dom = 2;      // axis of the largest normal component
};

struct Interval {  // filled fine cells k0..k1 of one column, and the class of the surface entered
  int k0, k1;
  std::uint8_t cls;
};

struct Crossing {
  double z;
  int sign;  // +1 entering (outward normal points down, -z), -1 leaving
  std::uint8_t cls;
};

// Casts after clamping, so that coordinates far outside the grid cannot overflow an int.
int clamp_int(double x, int lo, int hi) { return static_cast<int>(std::clamp(x, static_cast<double>(lo), static_cast<double>(hi))); }
// Closed cells [k, k+1] touching a coordinate interval [x, ...] from below / [..., x] from above.
int cell_lo(double x) { return clamp_int(std::ceil(x - kEps) - 1, -(1 << 30), 1 << 30); }
int cell_hi(double x) { return clamp_int(std::floor(x + kEps), -(1 << 30), 1 << 30); }

// A tile: fine cells [x0, x0 + fx) x [y0, y0 + fy) x [z0, z0 + fz); rows are indexed z * F + y.
struct Tile {
  int x0, y0, z0, fx, fy, fz;
};

using Row = std::uint64_t;

// Marks every fine cell of the tile that the triangle overlaps. The triangle is walked in columns
// along its dominant normal axis: the plane crosses at most a few cells of each column, and only
// those get the 9 edge-axis tests (the box-normal and plane tests hold by construction).
void rasterize(const Prepared& t, const Tile& tile, std::vector<Row>& rows) {
  const int tlo[3] = {tile.x0, tile.y0, tile.z0};
  const int thi[3] = {tile.x0 + tile.fx - 1, tile.y0 + tile.fy - 1, tile.z0 + tile.fz - 1};
  int lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::max(t.lo[a], tlo[a]);
    hi[a] = std::min(t.hi[a], thi[a]);
    if (lo[a] > hi[a]) return;
  }
  constexpr double half = 0.5 + kEps;
  // The 9 separating axes box-axis x edge, with the triangle's projection interval on each.
  Vec3 axis[9];
  double pmin[9], pmax[9], rad[9];
  const Vec3 e[3] = {sub3(t.v[1], t.v[0]), sub3(t.v[2], t.v[1]), sub3(t.v[0], t.v[2])};
  for (int i = 0; i < 3; ++i) {
    axis[3 * i + 0] = {0.0, -e[i][2], e[i][1]};
    axis[3 * i + 1] = {e[i][2], 0.0, -e[i][0]};
    axis[3 * i + 2] = {-e[i][1], e[i][0], 0.0};
  }
  for (int j = 0; j < 9; ++j) {
    const double p0 = dot3(axis[j], t.v[0]), p1 = dot3(axis[j], t.v[1]), p2 = dot3(axis[j], t.v[2]);
    pmin[j] = std::min({p0, p1, p2});
    pmax[j] = std::max({p0, p1, p2});
    rad[j] = half * (std::abs(axis[j][0]) + std::abs(axis[j][1]) + std::abs(axis[j][2]));
  }
  const int c = t.dom, a = (c + 1) % 3, b = (c + 2) % 3;
  const double inv = 1.0 / t.n[c];
  const double r = half * (std::abs(t.n[a]) + std::abs(t.n[b])) / std::abs(t.n[c]);
  int idx[3];
  Vec3 centre;
  for (int ia = lo[a]; ia <= hi[a]; ++ia) {
    idx[a] = ia;
    centre[a] = ia + 0.5;
    for (int ib = lo[b]; ib <= hi[b]; ++ib) {
      idx[b] = ib;
      centre[b] = ib + 0.5;
      // The plane's c-coordinate over this column's square is cc +- r.
      const double cc = (t.d - t.n[a] * centre[a] - t.n[b] * centre[b]) * inv;
      const int k0 = std::max(lo[c], cell_lo(cc - r)), k1 = std::min(hi[c], cell_hi(cc + r));
      for (int k = k0; k <= k1; ++k) {
        idx[c] = k;
        centre[c] = k + 0.5;
        bool hit = true;
        for (int j = 0; j < 9 && hit; ++j) {
          const double pc = dot3(axis[j], centre);
          hit = !(pmin[j] - pc > rad[j] || pmax[j] - pc < -rad[j]);
        }
        if (hit)
          rows[static_cast<std::size_t>(idx[2] - tile.z0) * kTileFine + static_cast<std::size_t>(idx[1] - tile.y0)] |=
              Row{1} << (idx[0] - tile.x0);
      }
    }
  }
}

// Edge test of a counter-clockwise 2D triangle with the top-left rule, computed in a canonical
// vertex order so that two triangles sharing an edge get bit-identical edge values: a ray
// through a shared edge or vertex then crosses exactly one of them (or, at a silhouette, both
// or neither, which leaves parity and winding unchanged).
bool inside_edge(double px, double py, double qx, double qy, double x, double y) {
  const bool flip = px > qx || (px == qx && py > qy);
  const double sx = flip ? qx : px, sy = flip ? qy : py, tx = flip ? px : qx, ty = flip ? py : qy;
  double e = (tx - sx) * (y - sy) - (ty - sy) * (x - sx);
  if (flip) e = -e;
  if (e != 0.0) return e > 0.0;
  const double dx = qx - px, dy = qy - py;
  return dy < 0.0 || (dy == 0.0 && dx > 0.0);
}

// Crossings of the +z rays through the centres of the tile column's fine columns.
void add_crossings(const Prepared& t, int x0, int y0, int fx, int fy, std::vector<std::vector<Crossing>>& cols) {
  if (t.n[2] == 0.0) return;  // parallel to the rays
  double ax = t.v[0][0], ay = t.v[0][1], bx = t.v[1][0], by = t.v[1][1], cx = t.v[2][0], cy = t.v[2][1];
  if (t.n[2] < 0.0) {  // make the projection counter-clockwise
    std::swap(bx, cx);
    std::swap(by, cy);
  }
  const double minx = std::min({ax, bx, cx}), maxx = std::max({ax, bx, cx});
  const double miny = std::min({ay, by, cy}), maxy = std::max({ay, by, cy});
  // Columns whose centre (i + 0.5, j + 0.5) lies in the projected bounding box.
  const int i0 = clamp_int(std::ceil(minx - 0.5), x0, x0 + fx), i1 = clamp_int(std::floor(maxx - 0.5), x0 - 1, x0 + fx - 1);
  const int j0 = clamp_int(std::ceil(miny - 0.5), y0, y0 + fy), j1 = clamp_int(std::floor(maxy - 0.5), y0 - 1, y0 + fy - 1);
  const int sign = t.n[2] < 0.0 ? +1 : -1;
  for (int j = j0; j <= j1; ++j)
    for (int i = i0; i <= i1; ++i) {
      const double x = i + 0.5, y = j + 0.5;
      if (inside_edge(ax, ay, bx, by, x, y) && inside_edge(bx, by, cx, cy, x, y) && inside_edge(cx, cy, ax, ay, x, y)) {
        const double z = (t.d - t.n[0] * x - t.n[1] * y) / t.n[2];
        cols[static_cast<std::size_t>(j - y0) * kTileFine + static_cast<std::size_t>(i - x0)].push_back({z, sign, t.cls});
      }
    }
}

// Compressed lists of (bin, triangle) pairs, triangles in input order within a bin.
struct Bins {
  std::vector<std::size_t> start;  // bins + 1
  std::vector<std::uint32_t> items;
  std::size_t size(std::size_t b) const { return start[b + 1] - start[b]; }
  const std::uint32_t* begin(std::size_t b) const { return items.data() + start[b]; }
};

Bins make_bins(std::size_t bins, const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs) {
  Bins out;
  out.start.assign(bins + 1, 0);
  for (const auto& p : pairs) ++out.start[p.first + 1];
  for (std::size_t b = 0; b < bins; ++b) out.start[b + 1] += out.start[b];
  out.items.resize(pairs.size());
  std::vector<std::size_t> fill(out.start.begin(), out.start.end() - 1);
  for (const auto& p : pairs) out.items[fill[p.first]++] = p.second;
  return out;
}

}  // namespace

VoxelizeResult voxelize(const TriangleMesh& mesh, const std::vector<TriangleClass>& part_class,
                        const VoxelizeOptions& opt, const Location& where, const RunContext& ctx) {
  const auto t_start = std::chrono::steady_clock::now();
  if (opt.resolution < 1 || opt.resolution > 8192)
    throw_invalid("voxelize: resolution " + std::to_string(opt.resolution) + " is out of range; allowed: 1..8192", where);
  if (opt.supersample < 1 || opt.supersample > kTileFine)
    throw_invalid("voxelize: supersample " + std::to_string(opt.supersample) + " is out of range; allowed: 1..64", where);
  if (opt.padding < 0 || opt.padding > 1024)
    throw_invalid("voxelize: padding " + std::to_string(opt.padding) + " is out of range; allowed: 0..1024", where);
  if (static_cast<long long>(opt.resolution) * opt.supersample > (1 << 24))
    throw_invalid("voxelize: resolution x supersample is too large (at most 16777216 fine cells per edge)", where);
  if (part_class.size() < mesh.parts.size())
    throw Error(ErrorCategory::Internal, "voxelize: no class for every mesh part", where);

  VoxelizeResult result;
  VoxelizeStats& st = result.stats;
  st.triangles = mesh.triangles.size();
  const std::size_t nv = mesh.vertices.size();

  // Which triangles have area (world units; relative to the longest edge so scale does not matter).
  std::vector<std::uint8_t> usable(mesh.triangles.size(), 0);
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    const auto& tri = mesh.triangles[i];
    if (tri[0] >= nv || tri[1] >= nv || tri[2] >= nv)
      throw_invalid(mesh.source + ": triangle " + std::to_string(i) + " refers to a vertex that does not exist", where);
    const Vec3 &a = mesh.vertices[tri[0]], &b = mesh.vertices[tri[1]], &c = mesh.vertices[tri[2]];
    for (const Vec3* p : {&a, &b, &c})
      if (!std::isfinite((*p)[0]) || !std::isfinite((*p)[1]) || !std::isfinite((*p)[2]))
        throw_invalid(mesh.source + ": triangle " + std::to_string(i) + " has a vertex that is not finite", where);
    const Vec3 e0 = sub3(b, a), e1 = sub3(c, a), e2 = sub3(c, b);
    const double l2 = std::max({dot3(e0, e0), dot3(e1, e1), dot3(e2, e2)});
    const Vec3 n = cross3(e0, e1);
    const double area2 = std::sqrt(dot3(n, n));
    if (l2 > 0.0 && area2 > 1e-12 * l2) usable[i] = 1;
    else ++st.degenerate;
  }

  // The box: given bounds, or the bounds of the triangles that have area.
  Vec3 bmin{}, bmax{};
  if (opt.has_bounds) {
    bmin = opt.bounds_min;
    bmax = opt.bounds_max;
    for (int a = 0; a < 3; ++a)
      if (!(bmax[a] > bmin[a]) || !std::isfinite(bmin[a]) || !std::isfinite(bmax[a]))
        throw_invalid("voxelize: bounds max must exceed min on every axis", where);
  } else {
    bmin = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
            std::numeric_limits<double>::infinity()};
    bmax = {-bmin[0], -bmin[1], -bmin[2]};
    for (std::size_t i = 0; i < mesh.triangles.size(); ++i)
      if (usable[i])
        for (std::uint32_t v : mesh.triangles[i])
          for (int a = 0; a < 3; ++a) {
            bmin[a] = std::min(bmin[a], mesh.vertices[v][a]);
            bmax[a] = std::max(bmax[a], mesh.vertices[v][a]);
          }
    if (!(bmin[0] <= bmax[0]))
      throw_invalid(mesh.source + ": all " + std::to_string(mesh.triangles.size()) +
                        " triangles have zero area; nothing to voxelise",
                    where);
  }
  const double longest = std::max({bmax[0] - bmin[0], bmax[1] - bmin[1], bmax[2] - bmin[2]});
  if (!(longest > 0.0)) throw_invalid(mesh.source + ": the mesh's bounding box has zero size", where);

  // Cubic nodes: `resolution` along the longest edge, centred on the box along the others.
  const int R = opt.resolution, S = opt.supersample, P = opt.padding;
  const double h = longest / R, hf = h / S;
  if (!(h >= kMinNodeSize))
    throw_invalid(mesh.source + ": nodes would be " + message_number(h) + " world units wide (box " +
                      message_number(longest) + " / resolution " + std::to_string(R) + "); allowed: at least " +
                      message_number(kMinNodeSize) + " (OpenVDB transforms): scale the mesh up or lower the resolution",
                  where);
  int n[3];
  Vec3 origin;  // world position of the corner of node (0, 0, 0)
  for (int a = 0; a < 3; ++a) {
    n[a] = std::clamp(static_cast<int>(std::ceil((bmax[a] - bmin[a]) / h - 1e-9)), 1, R);
    origin[a] = 0.5 * (bmin[a] + bmax[a]) - 0.5 * n[a] * h;
  }
  const int N[3] = {n[0] * S, n[1] * S, n[2] * S};
  st.fine_dims = {N[0], N[1], N[2]};

  ModelGrid& g = result.grid;
  g.dims = {n[0] + 2 * P, n[1] + 2 * P, n[2] + 2 * P};
  g.index_min = {-P, -P, -P};
  g.index_to_world = {h, 0, 0, origin[0] + 0.5 * h, 0, h, 0, origin[1] + 0.5 * h, 0, 0, h, origin[2] + 0.5 * h,
                      0, 0, 0, 1};
  const double bytes = static_cast<double>(g.dims.count()) * 5.0;
  const std::size_t avail = host_available_memory_bytes();
  if (avail > 0 && bytes > 0.5 * static_cast<double>(avail))
    throw Error(ErrorCategory::Unavailable,
                "voxelize: a " + std::to_string(g.dims.nx) + "x" + std::to_string(g.dims.ny) + "x" +
                    std::to_string(g.dims.nz) + " grid is too large for this machine's memory",
                where);
  g.density.assign(g.dims.count(), 0.0f);
  g.material.assign(g.dims.count(), kMaterialMedium);

  // Triangles in fine-index coordinates.
  std::vector<Prepared> prep(mesh.triangles.size());
  const long long ntri = static_cast<long long>(mesh.triangles.size());
  const int threads = ctx.threads > 0 ? ctx.threads : omp_get_max_threads();
#pragma omp parallel for schedule(static) num_threads(threads)
  for (long long i = 0; i < ntri; ++i) {
    if (!usable[static_cast<std::size_t>(i)]) continue;
    Prepared& t = prep[static_cast<std::size_t>(i)];
    const auto& tri = mesh.triangles[static_cast<std::size_t>(i)];
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a) t.v[k][a] = (mesh.vertices[tri[k]][a] - origin[a]) / hf;
    t.n = cross3(sub3(t.v[1], t.v[0]), sub3(t.v[2], t.v[0]));
    t.d = dot3(t.n, t.v[0]);
    t.dom = 0;
    for (std::uint8_t a = 1; a < 3; ++a)
      if (std::abs(t.n[a]) > std::abs(t.n[t.dom])) t.dom = a;
    for (int a = 0; a < 3; ++a) {
      const double mn = std::min({t.v[0][a], t.v[1][a], t.v[2][a]}), mx = std::max({t.v[0][a], t.v[1][a], t.v[2][a]});
      t.lo[a] = clamp_int(std::ceil(mn - kEps) - 1, 0, N[a]);
      t.hi[a] = clamp_int(std::floor(mx + kEps), -1, N[a] - 1);
    }
    t.cls = static_cast<std::uint8_t>(part_class[mesh.triangle_part[static_cast<std::size_t>(i)]]);
  }

  // Tiles of C^3 nodes = F^3 fine cells (F <= 64), and which triangles overlap each.
  const int C = std::max(1, kTileFine / S), F = C * S;
  const int T[3] = {(n[0] + C - 1) / C, (n[1] + C - 1) / C, (n[2] + C - 1) / C};
  const std::size_t tiles3 = static_cast<std::size_t>(T[0]) * T[1] * T[2];
  const std::size_t tiles2 = static_cast<std::size_t>(T[0]) * T[1];
  if (tiles3 >= (std::size_t{1} << 31))
    throw Error(ErrorCategory::Unavailable, "voxelize: the fine grid is too large (more than 2^31 tiles)", where);
  const bool fill = opt.fill != FillMode::None;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs, pairs2;
  for (std::size_t i = 0; i < prep.size(); ++i) {
    if (!usable[i]) continue;
    const Prepared& t = prep[i];
    const bool in_xy = t.lo[0] <= t.hi[0] && t.lo[1] <= t.hi[1];
    int tl[3], th[3];
    for (int a = 0; a < 3; ++a) {
      tl[a] = t.lo[a] / F;
      th[a] = t.hi[a] / F;
    }
    // Fill needs every crossing of a column's ray, also those below or above the box.
    if (fill && in_xy && t.n[2] != 0.0)
      for (int ty = tl[1]; ty <= th[1]; ++ty)
        for (int tx = tl[0]; tx <= th[0]; ++tx)
          pairs2.push_back({static_cast<std::uint32_t>(static_cast<std::size_t>(ty) * T[0] + tx), static_cast<std::uint32_t>(i)});
    if (!in_xy || t.lo[2] > t.hi[2]) {
      ++st.outside;
      continue;
    }
    const bool single = tl[0] == th[0] && tl[1] == th[1] && tl[2] == th[2];
    bool any = false;
    for (int tz = tl[2]; tz <= th[2]; ++tz)
      for (int ty = tl[1]; ty <= th[1]; ++ty)
        for (int tx = tl[0]; tx <= th[0]; ++tx) {
          if (!single) {
            const int t0[3] = {tx * F, ty * F, tz * F};
            Vec3 centre, half;
            for (int a = 0; a < 3; ++a) {
              const int w = std::min(F, N[a] - t0[a]);
              centre[a] = t0[a] + 0.5 * w;
              half[a] = 0.5 * w + kEps;
            }
            if (!triangle_box_overlap(t.v[0], t.v[1], t.v[2], centre, half)) continue;
          }
          any = true;
          pairs.push_back({static_cast<std::uint32_t>((static_cast<std::size_t>(tz) * T[1] + ty) * T[0] + tx),
                           static_cast<std::uint32_t>(i)});
        }
    if (!any) ++st.outside;
  }
  if (st.outside + st.degenerate == st.triangles)
    throw_invalid(mesh.source + ": no triangle with non-zero area lies inside the voxelisation box (" +
                      std::to_string(st.degenerate) + " degenerate, " + std::to_string(st.outside) + " outside)",
                  where);
  const Bins bins = make_bins(tiles3, pairs);
  const Bins bins2 = fill ? make_bins(tiles2, pairs2) : Bins{};
  pairs.clear();
  pairs.shrink_to_fit();
  pairs2.clear();
  pairs2.shrink_to_fit();

  // Per-coarse-cell bit masks within a 64-bit row.
  std::vector<Row> cmask(static_cast<std::size_t>(C));
  for (int ci = 0; ci < C; ++ci) cmask[ci] = (S == 64 ? ~Row{0} : ((Row{1} << S) - 1)) << (ci * S);
  const double inv_cells = 1.0 / (static_cast<double>(S) * S * S);

  std::uint64_t occ_total = 0, leaf_total = 0, wood_total = 0, open_total = 0;
  std::size_t occupied_nodes = 0, brown_nodes = 0;
  const long long columns = static_cast<long long>(tiles2);
#pragma omp parallel num_threads(threads) reduction(+ : occ_total, leaf_total, wood_total, open_total, occupied_nodes, brown_nodes)
  {
    std::vector<Row> leaf(static_cast<std::size_t>(kTileFine) * kTileFine), wood(leaf.size());
    std::vector<std::vector<Crossing>> cross(fill ? leaf.size() : 0);
    std::vector<std::vector<Interval>> filled(fill ? leaf.size() : 0);
    std::vector<std::uint32_t> cnt_occ(static_cast<std::size_t>(C) * C * C), cnt_leaf(cnt_occ.size()),
        cnt_wood(cnt_occ.size());
#pragma omp for schedule(dynamic, 1)
    for (long long col = 0; col < columns; ++col) {
      if (ctx.cancelled()) continue;  // no throw inside OpenMP
      const int tx = static_cast<int>(col % T[0]), ty = static_cast<int>(col / T[0]);
      const int x0 = tx * F, y0 = ty * F, fx = std::min(F, N[0] - x0), fy = std::min(F, N[1] - y0);
      // Solid fill: intervals of inside cells per fine column, from sorted ray crossings.
      int fill_lo = std::numeric_limits<int>::max(), fill_hi = -1;
      if (fill && bins2.size(static_cast<std::size_t>(col)) > 0) {
        for (auto& c : cross) c.clear();
        for (auto& f : filled) f.clear();
        const std::uint32_t* it = bins2.begin(static_cast<std::size_t>(col));
        for (std::size_t q = 0; q < bins2.size(static_cast<std::size_t>(col)); ++q) add_crossings(prep[it[q]], x0, y0, fx, fy, cross);
        for (int yl = 0; yl < fy; ++yl)
          for (int xl = 0; xl < fx; ++xl) {
            auto& cl = cross[static_cast<std::size_t>(yl) * kTileFine + xl];
            if (cl.empty()) continue;
            std::sort(cl.begin(), cl.end(), [](const Crossing& p, const Crossing& q) { return p.z < q.z; });
            int w = 0;
            double zin = 0;
            std::uint8_t cls = 0;
            auto inside = [&](int x) { return opt.fill == FillMode::Parity ? (x & 1) != 0 : x != 0; };
            for (const Crossing& cr : cl) {
              const bool was = inside(w);
              w = opt.fill == FillMode::Parity ? (w ^ 1) : w + cr.sign;
              const bool now = inside(w);
              if (!was && now) {
                zin = cr.z;
                cls = cr.cls;
              } else if (was && !now) {
                // Cells whose centre k + 0.5 lies strictly between the two crossings.
                const int k0 = clamp_int(std::floor(zin - 0.5) + 1, 0, N[2]);
                const int k1 = clamp_int(std::ceil(cr.z - 0.5) - 1, -1, N[2] - 1);
                if (k0 <= k1) {
                  filled[static_cast<std::size_t>(yl) * kTileFine + xl].push_back({k0, k1, cls});
                  fill_lo = std::min(fill_lo, k0);
                  fill_hi = std::max(fill_hi, k1);
                }
              }
            }
            if (w != 0) ++open_total;  // not closed along this ray: the open end stays empty
          }
      }
      for (int tz = 0; tz < T[2]; ++tz) {
        const std::size_t tile_index = (static_cast<std::size_t>(tz) * T[1] + ty) * T[0] + tx;
        const int z0 = tz * F, fz = std::min(F, N[2] - z0);
        const bool has_fill = fill_hi >= z0 && fill_lo < z0 + fz;
        if (bins.size(tile_index) == 0 && !has_fill) continue;
        const Tile tile{x0, y0, z0, fx, fy, fz};
        std::fill(leaf.begin(), leaf.end(), 0);
        std::fill(wood.begin(), wood.end(), 0);
        const std::uint32_t* it = bins.begin(tile_index);
        for (std::size_t q = 0; q < bins.size(tile_index); ++q) {
          const Prepared& t = prep[it[q]];
          rasterize(t, tile, t.cls == static_cast<std::uint8_t>(TriangleClass::Wood) ? wood : leaf);
        }
        if (has_fill)
          for (int yl = 0; yl < fy; ++yl)
            for (int xl = 0; xl < fx; ++xl)
              for (const Interval& iv : filled[static_cast<std::size_t>(yl) * kTileFine + xl]) {
                const int k0 = std::max(iv.k0, z0), k1 = std::min(iv.k1, z0 + fz - 1);
                auto& rows = iv.cls == static_cast<std::uint8_t>(TriangleClass::Wood) ? wood : leaf;
                for (int k = k0; k <= k1; ++k)
                  rows[static_cast<std::size_t>(k - z0) * kTileFine + static_cast<std::size_t>(yl)] |= Row{1} << xl;
              }
        // Box filter: count fine cells per node.
        std::fill(cnt_occ.begin(), cnt_occ.end(), 0);
        std::fill(cnt_leaf.begin(), cnt_leaf.end(), 0);
        std::fill(cnt_wood.begin(), cnt_wood.end(), 0);
        const int cx = (fx + S - 1) / S;
        for (int zl = 0; zl < fz; ++zl)
          for (int yl = 0; yl < fy; ++yl) {
            const std::size_t r = static_cast<std::size_t>(zl) * kTileFine + static_cast<std::size_t>(yl);
            const Row lw = leaf[r], ww = wood[r], ow = lw | ww;
            if (ow == 0) continue;
            const std::size_t base = (static_cast<std::size_t>(zl / S) * C + static_cast<std::size_t>(yl / S)) * C;
            for (int ci = 0; ci < cx; ++ci) {
              const Row m = cmask[ci];
              if ((ow & m) == 0) continue;
              cnt_occ[base + ci] += static_cast<std::uint32_t>(__builtin_popcountll(ow & m));
              cnt_leaf[base + ci] += static_cast<std::uint32_t>(__builtin_popcountll(lw & m));
              cnt_wood[base + ci] += static_cast<std::uint32_t>(__builtin_popcountll(ww & m));
            }
          }
        const int cy = (fy + S - 1) / S, cz = (fz + S - 1) / S;
        for (int ck = 0; ck < cz; ++ck)
          for (int cj = 0; cj < cy; ++cj)
            for (int ci = 0; ci < cx; ++ci) {
              const std::size_t l = (static_cast<std::size_t>(ck) * C + cj) * C + ci;
              if (cnt_occ[l] == 0) continue;
              const std::size_t out =
                  g.dims.index(tx * C + ci + P, ty * C + cj + P, tz * C + ck + P);
              g.density[out] = static_cast<float>(cnt_occ[l] * inv_cells);
              const bool brown = cnt_wood[l] > cnt_leaf[l];
              g.material[out] = brown ? kMaterialWood : kMaterialMedium;
              occ_total += cnt_occ[l];
              leaf_total += cnt_leaf[l];
              wood_total += cnt_wood[l];
              ++occupied_nodes;
              brown_nodes += brown;
            }
      }
    }
  }
  ctx.check_cancelled();
  st.fine_occupied = occ_total;
  st.fine_leaf = leaf_total;
  st.fine_wood = wood_total;
  st.fine_both = leaf_total + wood_total - occ_total;
  st.open_columns = open_total;
  st.occupied_nodes = occupied_nodes;
  st.brown_nodes = brown_nodes;
  st.threads = threads;
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return result;
}

}  // namespace lblight
