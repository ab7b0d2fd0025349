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

void check_options(const TriangleMesh& mesh, const std::vector<TriangleClass>& part_class, const VoxelizeOptions& opt,
                   const Location& where) {
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
}

// Which triangles have area (world units; relative to the longest edge so scale does not matter).
std::vector<std::uint8_t> usable_triangles(const TriangleMesh& mesh, const Location& where, VoxelizeStats& st) {
  const std::size_t nv = mesh.vertices.size();
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
  return usable;
}

// Cubic nodes: `resolution` along the longest edge of the box, centred on it along the others;
// `supersample` fine cells per node and axis.
struct Layout {
  int S = 1, P = 0;  // supersample, padding
  double h = 0, hf = 0;  // node and fine-cell edge (world units)
  int n[3] = {0, 0, 0}, N[3] = {0, 0, 0};  // nodes and fine cells per axis (no padding)
  Vec3 origin{};  // world position of the corner of node (0, 0, 0)
};

// The box (given bounds, or the bounds of the triangles that have area) and the node layout on it.
Layout node_layout(const TriangleMesh& mesh, const std::vector<std::uint8_t>& usable, const VoxelizeOptions& opt,
                   const Location& where) {
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

  Layout l;
  const int R = opt.resolution;
  l.S = opt.supersample;
  l.P = opt.padding;
  l.h = longest / R;
  l.hf = l.h / l.S;
  if (!(l.h >= kMinNodeSize))
    throw_invalid(mesh.source + ": nodes would be " + message_number(l.h) + " world units wide (box " +
                      message_number(longest) + " / resolution " + std::to_string(R) + "); allowed: at least " +
                      message_number(kMinNodeSize) + " (OpenVDB transforms): scale the mesh up or lower the resolution",
                  where);
  for (int a = 0; a < 3; ++a) {
    l.n[a] = std::clamp(static_cast<int>(std::ceil((bmax[a] - bmin[a]) / l.h - 1e-9)), 1, R);
    l.origin[a] = 0.5 * (bmin[a] + bmax[a]) - 0.5 * l.n[a] * l.h;
    l.N[a] = l.n[a] * l.S;
  }
  return l;
}

// The output grid of the layout, empty, with its transform; refused when it would not fit in memory.
void allocate_grid(const Layout& l, const Location& where, ModelGrid& g) {
  const int P = l.P;
  const double h = l.h;
  g.dims = {l.n[0] + 2 * P, l.n[1] + 2 * P, l.n[2] + 2 * P};
  g.index_min = {-P, -P, -P};
  g.index_to_world = {h, 0, 0, l.origin[0] + 0.5 * h, 0, h, 0, l.origin[1] + 0.5 * h, 0, 0, h, l.origin[2] + 0.5 * h,
                      0, 0, 0, 1};
  check_host_memory(static_cast<double>(g.dims.count()) * 5.0,
                    "voxelize: a " + std::to_string(g.dims.nx) + "x" + std::to_string(g.dims.ny) + "x" +
                        std::to_string(g.dims.nz) + " grid",
                    "lower the resolution", where);
  g.density.assign(g.dims.count(), 0.0f);
  g.material.assign(g.dims.count(), kMaterialMedium);
}

// Triangles in fine-index coordinates.
std::vector<Prepared> prepare_triangles(const TriangleMesh& mesh, const std::vector<std::uint8_t>& usable,
                                        const std::vector<TriangleClass>& part_class, const Layout& l, int threads) {
  std::vector<Prepared> prep(mesh.triangles.size());
  const long long ntri = static_cast<long long>(mesh.triangles.size());
#pragma omp parallel for schedule(static) num_threads(threads)
  for (long long i = 0; i < ntri; ++i) {
    if (!usable[static_cast<std::size_t>(i)]) continue;
    Prepared& t = prep[static_cast<std::size_t>(i)];
    const auto& tri = mesh.triangles[static_cast<std::size_t>(i)];
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a) t.v[k][a] = (mesh.vertices[tri[k]][a] - l.origin[a]) / l.hf;
    t.n = cross3(sub3(t.v[1], t.v[0]), sub3(t.v[2], t.v[0]));
    t.d = dot3(t.n, t.v[0]);
    t.dom = 0;
    for (std::uint8_t a = 1; a < 3; ++a)
      if (std::abs(t.n[a]) > std::abs(t.n[t.dom])) t.dom = a;
    for (int a = 0; a < 3; ++a) {
      const double mn = std::min({t.v[0][a], t.v[1][a], t.v[2][a]}), mx = std::max({t.v[0][a], t.v[1][a], t.v[2][a]});
      t.lo[a] = clamp_int(std::ceil(mn - kEps) - 1, 0, l.N[a]);
      t.hi[a] = clamp_int(std::floor(mx + kEps), -1, l.N[a] - 1);
    }
    t.cls = static_cast<std::uint8_t>(part_class[mesh.triangle_part[static_cast<std::size_t>(i)]]);
  }
  return prep;
}

// Tiles of C^3 nodes = F^3 fine cells (F <= 64), and which triangles overlap each: `tiles` per
// 3D tile (rasterised), `columns` per tile column (ray crossings for solid fill, also those below
// or above the box).
struct TileBins {
  int C = 1, F = 1;
  int T[3] = {0, 0, 0};
  Bins tiles, columns;
  std::size_t tile_index(int tx, int ty, int tz) const {
    return (static_cast<std::size_t>(tz) * T[1] + ty) * T[0] + tx;
  }
};

TileBins bin_triangles(const TriangleMesh& mesh, const std::vector<Prepared>& prep,
                       const std::vector<std::uint8_t>& usable, const Layout& l, bool fill, const Location& where,
                       VoxelizeStats& st) {
  TileBins tb;
  tb.C = std::max(1, kTileFine / l.S);
  tb.F = tb.C * l.S;
  const int C = tb.C, F = tb.F;
  for (int a = 0; a < 3; ++a) tb.T[a] = (l.n[a] + C - 1) / C;
  const int* T = tb.T;
  const std::size_t tiles3 = static_cast<std::size_t>(T[0]) * T[1] * T[2];
  const std::size_t tiles2 = static_cast<std::size_t>(T[0]) * T[1];
  if (tiles3 >= (std::size_t{1} << 31))
    throw Error(ErrorCategory::Unavailable, "voxelize: the fine grid is too large (more than 2^31 tiles)", where);
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
              const int w = std::min(F, l.N[a] - t0[a]);
              centre[a] = t0[a] + 0.5 * w;
              half[a] = 0.5 * w + kEps;
            }
            if (!triangle_box_overlap(t.v[0], t.v[1], t.v[2], centre, half)) continue;
          }
          any = true;
          pairs.push_back({static_cast<std::uint32_t>(tb.tile_index(tx, ty, tz)), static_cast<std::uint32_t>(i)});
        }
    if (!any) ++st.outside;
  }
  if (st.outside + st.degenerate == st.triangles)
    throw_invalid(mesh.source + ": no triangle with non-zero area lies inside the voxelisation box (" +
                      std::to_string(st.degenerate) + " degenerate, " + std::to_string(st.outside) + " outside)",
                  where);
  tb.tiles = make_bins(tiles3, pairs);
  if (fill) tb.columns = make_bins(tiles2, pairs2);
  return tb;
}

// Fine-cell counts a thread adds up (integers: the sum does not depend on the order).
struct Counts {
  std::uint64_t occupied = 0, leaf = 0, wood = 0, open = 0;
  std::size_t nodes = 0, brown = 0;
};

// One thread's buffers for a tile column: fine-cell rows of a tile, ray crossings and filled
// intervals per fine column, fine-cell counts per node of a tile.
struct ColumnScratch {
  std::vector<Row> leaf, wood;
  std::vector<std::vector<Crossing>> cross;
  std::vector<std::vector<Interval>> filled;
  std::vector<std::uint32_t> cnt_occ, cnt_leaf, cnt_wood;
  ColumnScratch(int C, bool fill)
      : leaf(static_cast<std::size_t>(kTileFine) * kTileFine),
        wood(leaf.size()),
        cross(fill ? leaf.size() : 0),
        filled(fill ? leaf.size() : 0),
        cnt_occ(static_cast<std::size_t>(C) * C * C),
        cnt_leaf(cnt_occ.size()),
        cnt_wood(cnt_occ.size()) {}
};

// Solid fill of one tile column (fine columns [x0, x0 + fx) x [y0, y0 + fy)): intervals of inside
// cells per fine column, from the sorted ray crossings; [fill_lo, fill_hi]: the cells any of them covers.
void fill_column(const std::vector<Prepared>& prep, const Bins& columns, long long col, int x0, int y0, int fx, int fy,
                 FillMode mode, int nz_fine, ColumnScratch& sc, int& fill_lo, int& fill_hi, Counts& counts) {
  for (auto& c : sc.cross) c.clear();
  for (auto& f : sc.filled) f.clear();
  const std::uint32_t* it = columns.begin(static_cast<std::size_t>(col));
  for (std::size_t q = 0; q < columns.size(static_cast<std::size_t>(col)); ++q)
    add_crossings(prep[it[q]], x0, y0, fx, fy, sc.cross);
  for (int yl = 0; yl < fy; ++yl)
    for (int xl = 0; xl < fx; ++xl) {
      auto& cl = sc.cross[static_cast<std::size_t>(yl) * kTileFine + xl];
      if (cl.empty()) continue;
      std::sort(cl.begin(), cl.end(), [](const Crossing& p, const Crossing& q) { return p.z < q.z; });
      int w = 0;
      double zin = 0;
      std::uint8_t cls = 0;
      auto inside = [&](int x) { return mode == FillMode::Parity ? (x & 1) != 0 : x != 0; };
      for (const Crossing& cr : cl) {
        const bool was = inside(w);
        w = mode == FillMode::Parity ? (w ^ 1) : w + cr.sign;
        const bool now = inside(w);
        if (!was && now) {
          zin = cr.z;
          cls = cr.cls;
        } else if (was && !now) {
          // Cells whose centre k + 0.5 lies strictly between the two crossings.
          const int k0 = clamp_int(std::floor(zin - 0.5) + 1, 0, nz_fine);
          const int k1 = clamp_int(std::ceil(cr.z - 0.5) - 1, -1, nz_fine - 1);
          if (k0 <= k1) {
            sc.filled[static_cast<std::size_t>(yl) * kTileFine + xl].push_back({k0, k1, cls});
            fill_lo = std::min(fill_lo, k0);
            fill_hi = std::max(fill_hi, k1);
          }
        }
      }
      if (w != 0) ++counts.open;  // not closed along this ray: the open end stays empty
    }
}

// One tile: rasterise its triangles and filled intervals into fine-cell rows, then box-filter
// them into its nodes of `g` (density = touched fraction, brown where wood touches more cells).
void voxelize_tile(const std::vector<Prepared>& prep, const TileBins& tb, const Layout& l, const Tile& tile, int tx,
                   int ty, int tz, bool has_fill, ColumnScratch& sc, ModelGrid& g, Counts& counts) {
  const int S = l.S, C = tb.C, P = l.P;
  const int fx = tile.fx, fy = tile.fy, fz = tile.fz, z0 = tile.z0;
  std::fill(sc.leaf.begin(), sc.leaf.end(), 0);
  std::fill(sc.wood.begin(), sc.wood.end(), 0);
  const std::size_t tile_index = tb.tile_index(tx, ty, tz);
  const std::uint32_t* it = tb.tiles.begin(tile_index);
  for (std::size_t q = 0; q < tb.tiles.size(tile_index); ++q) {
    const Prepared& t = prep[it[q]];
    rasterize(t, tile, t.cls == static_cast<std::uint8_t>(TriangleClass::Wood) ? sc.wood : sc.leaf);
  }
  if (has_fill)
    for (int yl = 0; yl < fy; ++yl)
      for (int xl = 0; xl < fx; ++xl)
        for (const Interval& iv : sc.filled[static_cast<std::size_t>(yl) * kTileFine + xl]) {
          const int k0 = std::max(iv.k0, z0), k1 = std::min(iv.k1, z0 + fz - 1);
          auto& rows = iv.cls == static_cast<std::uint8_t>(TriangleClass::Wood) ? sc.wood : sc.leaf;
          for (int k = k0; k <= k1; ++k)
            rows[static_cast<std::size_t>(k - z0) * kTileFine + static_cast<std::size_t>(yl)] |= Row{1} << xl;
        }
  // Box filter: count fine cells per node, through per-node bit masks within a 64-bit row.
  std::fill(sc.cnt_occ.begin(), sc.cnt_occ.end(), 0);
  std::fill(sc.cnt_leaf.begin(), sc.cnt_leaf.end(), 0);
  std::fill(sc.cnt_wood.begin(), sc.cnt_wood.end(), 0);
  const Row node_bits = S == 64 ? ~Row{0} : ((Row{1} << S) - 1);
  const int cx = (fx + S - 1) / S;
  for (int zl = 0; zl < fz; ++zl)
    for (int yl = 0; yl < fy; ++yl) {
      const std::size_t r = static_cast<std::size_t>(zl) * kTileFine + static_cast<std::size_t>(yl);
      const Row lw = sc.leaf[r], ww = sc.wood[r], ow = lw | ww;
      if (ow == 0) continue;
      const std::size_t base = (static_cast<std::size_t>(zl / S) * C + static_cast<std::size_t>(yl / S)) * C;
      for (int ci = 0; ci < cx; ++ci) {
        const Row m = node_bits << (ci * S);
        if ((ow & m) == 0) continue;
        sc.cnt_occ[base + ci] += static_cast<std::uint32_t>(__builtin_popcountll(ow & m));
        sc.cnt_leaf[base + ci] += static_cast<std::uint32_t>(__builtin_popcountll(lw & m));
        sc.cnt_wood[base + ci] += static_cast<std::uint32_t>(__builtin_popcountll(ww & m));
      }
    }
  const double inv_cells = 1.0 / (static_cast<double>(S) * S * S);
  const int cy = (fy + S - 1) / S, cz = (fz + S - 1) / S;
  for (int ck = 0; ck < cz; ++ck)
    for (int cj = 0; cj < cy; ++cj)
      for (int ci = 0; ci < cx; ++ci) {
        const std::size_t n = (static_cast<std::size_t>(ck) * C + cj) * C + ci;
        if (sc.cnt_occ[n] == 0) continue;
        const std::size_t out = g.dims.index(tx * C + ci + P, ty * C + cj + P, tz * C + ck + P);
        g.density[out] = static_cast<float>(sc.cnt_occ[n] * inv_cells);
        const bool brown = sc.cnt_wood[n] > sc.cnt_leaf[n];
        g.material[out] = brown ? kMaterialWood : kMaterialMedium;
        counts.occupied += sc.cnt_occ[n];
        counts.leaf += sc.cnt_leaf[n];
        counts.wood += sc.cnt_wood[n];
        ++counts.nodes;
        counts.brown += brown;
      }
}

}  // namespace

VoxelizeResult voxelize(const TriangleMesh& mesh, const std::vector<TriangleClass>& part_class,
                        const VoxelizeOptions& opt, const Location& where, const RunContext& ctx) {
  const auto t_start = std::chrono::steady_clock::now();
  check_options(mesh, part_class, opt, where);
  VoxelizeResult result;
  VoxelizeStats& st = result.stats;
  st.triangles = mesh.triangles.size();
  const std::vector<std::uint8_t> usable = usable_triangles(mesh, where, st);
  const Layout l = node_layout(mesh, usable, opt, where);
  st.fine_dims = {l.N[0], l.N[1], l.N[2]};
  ModelGrid& g = result.grid;
  allocate_grid(l, where, g);

  const int threads = ctx.threads > 0 ? ctx.threads : omp_get_max_threads();
  const std::vector<Prepared> prep = prepare_triangles(mesh, usable, part_class, l, threads);
  const bool fill = opt.fill != FillMode::None;
  const TileBins tb = bin_triangles(mesh, prep, usable, l, fill, where, st);

  // Tile columns in parallel: each writes only its own nodes.
  Counts total;
  const long long columns = static_cast<long long>(tb.T[0]) * tb.T[1];
#pragma omp parallel num_threads(threads)
  {
    ColumnScratch sc(tb.C, fill);
    Counts mine;
#pragma omp for schedule(dynamic, 1)
    for (long long col = 0; col < columns; ++col) {
      if (ctx.cancelled()) continue;  // no throw inside OpenMP
      const int tx = static_cast<int>(col % tb.T[0]), ty = static_cast<int>(col / tb.T[0]);
      const int x0 = tx * tb.F, y0 = ty * tb.F, fx = std::min(tb.F, l.N[0] - x0), fy = std::min(tb.F, l.N[1] - y0);
      int fill_lo = std::numeric_limits<int>::max(), fill_hi = -1;
      if (fill && tb.columns.size(static_cast<std::size_t>(col)) > 0)
        fill_column(prep, tb.columns, col, x0, y0, fx, fy, opt.fill, l.N[2], sc, fill_lo, fill_hi, mine);
      for (int tz = 0; tz < tb.T[2]; ++tz) {
        const int z0 = tz * tb.F, fz = std::min(tb.F, l.N[2] - z0);
        const bool has_fill = fill_hi >= z0 && fill_lo < z0 + fz;
        if (tb.tiles.size(tb.tile_index(tx, ty, tz)) == 0 && !has_fill) continue;
        voxelize_tile(prep, tb, l, {x0, y0, z0, fx, fy, fz}, tx, ty, tz, has_fill, sc, g, mine);
      }
    }
#pragma omp critical
    {
      total.occupied += mine.occupied;
      total.leaf += mine.leaf;
      total.wood += mine.wood;
      total.open += mine.open;
      total.nodes += mine.nodes;
      total.brown += mine.brown;
    }
  }
  ctx.check_cancelled();
  st.fine_occupied = total.occupied;
  st.fine_leaf = total.leaf;
  st.fine_wood = total.wood;
  st.fine_both = total.leaf + total.wood - total.occupied;
  st.open_columns = total.open;
  st.occupied_nodes = total.nodes;
  st.brown_nodes = total.brown;
  st.threads = threads;
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return result;
}

}  // namespace lblight
