#include "lblight/scene/forest_coarse.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "lblight/core/system_info.h"
#include "lblight/lattice/trilinear.h"

namespace lblight {
namespace {

// Extinction-weighted sums of the voxels' materials, per channel.
struct ExtinctionSums {
  std::array<double, kChannels> absorb{}, scatter{}, scatter_g{};
  double extinction = 0;       // channel mean
  double absorbing_share = 0;  // extinction of materials that dump f_0
  void add(const Material& m, double rho_weight) {
    double mean = 0;
    for (int c = 0; c < kChannels; ++c) {
      absorb[c] += rho_weight * m.channel[c].sigma_a;
      scatter[c] += rho_weight * m.channel[c].sigma_s;
      scatter_g[c] += rho_weight * m.channel[c].sigma_s * m.channel[c].g;
      mean += m.channel[c].sigma_t() / kChannels;
    }
    extinction += rho_weight * mean;
    if (m.absorbs) absorbing_share += rho_weight * mean;
  }
};

double mean_sigma_t(const Material& m) {
  double s = 0;
  for (const auto& c : m.channel) s += c.sigma_t() / kChannels;
  return s;
}

double voxel_edge(const ModelGrid& g) { return frame_voxel_edge(g.frame()); }

// The cells an instance's voxels deposit into (the two cells around each voxel centre per axis),
// in cell indices.
void instance_cells(const ForestModel& fm, const InstanceTransform& t, double cell, std::array<std::int64_t, 3>& lo,
                    std::array<std::int64_t, 3>& hi) {
  Vec3d mn, mx;
  instance_world_bounds(fm.grid->frame(), t, 0.5, mn, mx);
  const double a[3] = {mn.x, mn.y, mn.z}, b[3] = {mx.x, mx.y, mx.z};
  for (int k = 0; k < 3; ++k) {
    lo[k] = static_cast<std::int64_t>(std::floor(a[k] / cell));
    hi[k] = static_cast<std::int64_t>(std::floor(b[k] / cell)) + 1;
  }
}

// Adds `value` at world point p to the 8 cells around it, weighted trilinearly (cloud in cell):
// cell (i, j, k) is centred at cell * (i, j, k), lo is the grid's first cell. Nearest-cell
// deposit made the coarse light depend on where an instance sits within a cell (the grids of an
// instance and of its model alone differ by that offset), which left the factors' largest error
// (docs/forest.md sec. 2).
void deposit_trilinear(std::vector<double>& depth, const Dims& dims, const std::array<std::int64_t, 3>& lo, double cell,
                       const Vec3d& p, double value) {
  std::array<double, 3> u{p.x / cell - static_cast<double>(lo[0]), p.y / cell - static_cast<double>(lo[1]),
                          p.z / cell - static_cast<double>(lo[2])};
  // a centre on a cell centre up to rounding: all of it there, no 1e-16 share in a cell that
  // would otherwise stay empty (and grow the cropped lattice, or reach the ground's layer)
  for (double& v : u)
    if (std::abs(v - std::round(v)) < 1e-9) v = std::round(v);
  const Trilinear t(dims, u);
  for (int c = 0; c < 8; ++c)
    if (t.weight[c] != 0.0) depth[t.index[c]] += value * t.weight[c];
}

// Deposits the instances into one coarse grid (the forest, or one model alone).
CoarseGrid deposit(const std::vector<ForestModel>& models, const std::vector<ForestInstance>& instances, double cell,
                   const Location& where, const std::string& what) {
  std::array<std::int64_t, 3> lo{std::numeric_limits<std::int64_t>::max(), std::numeric_limits<std::int64_t>::max(),
                                 std::numeric_limits<std::int64_t>::max()};
  std::array<std::int64_t, 3> hi{std::numeric_limits<std::int64_t>::min(), std::numeric_limits<std::int64_t>::min(),
                                 std::numeric_limits<std::int64_t>::min()};
  for (const ForestInstance& in : instances) {
    std::array<std::int64_t, 3> a, b;
    instance_cells(forest_model(models, in.model), InstanceTransform(in), cell, a, b);
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], a[k]);
      hi[k] = std::max(hi[k], b[k]);
    }
  }
  check_index_box(lo, hi, what + " (cell size " + message_number(cell) + ")", where);
  const Dims dims{static_cast<int>(hi[0] - lo[0] + 1), static_cast<int>(hi[1] - lo[1] + 1), static_cast<int>(hi[2] - lo[2] + 1)};
  check_host_memory(static_cast<double>(dims.count()) * 2 * (4 + 8 + 5), what + " (" + std::to_string(dims.nx) + "x" +
                        std::to_string(dims.ny) + "x" + std::to_string(dims.nz) + " cells of " + message_number(cell) + ")",
                    "use a larger forest.coarse.cell_size, or \"coarse\": false", where);
  // Optical depth per cell, and the extinction-weighted sums for the coarse material.
  std::vector<double> depth(dims.count(), 0.0);
  ExtinctionSums sums;
  for (const ForestInstance& in : instances) {
    const ForestModel& fm = forest_model(models, in.model);
    const ModelGrid& g = *fm.grid;
    const DenseFrame frame = g.frame();
    const InstanceTransform t(in);
    const double w = std::pow(in.scale * voxel_edge(g) / cell, 2);
    const Material* mats[2] = {&fm.spec->material, &fm.spec->wood_material};
    const double st[2] = {mean_sigma_t(*mats[0]), mean_sigma_t(*mats[1])};
    for (int k = 0; k < g.dims.nz; ++k)
      for (int j = 0; j < g.dims.ny; ++j)
        for (int i = 0; i < g.dims.nx; ++i) {
          const std::size_t n = g.dims.index(i, j, k);
          const float rho = g.density[n];
          if (!(rho > 0.0f)) continue;
          const int kind = g.material[n] == kMaterialWood ? 1 : 0;
          deposit_trilinear(depth, dims, lo, cell, t.to_world(frame_to_world(frame, i, j, k)), rho * st[kind] * w);
          sums.add(*mats[kind], rho * w);
        }
  }
  CoarseGrid out;
  ModelGrid& g = out.grid;
  g.dims = dims;
  g.index_min = {static_cast<int>(lo[0]), static_cast<int>(lo[1]), static_cast<int>(lo[2])};
  g.index_to_world = {cell, 0, 0, 0, 0, cell, 0, 0, 0, 0, cell, 0, 0, 0, 0, 1};
  g.density.assign(dims.count(), 0.0f);
  g.material.assign(dims.count(), kMaterialMedium);
  g.description = what + ": " + std::to_string(instances.size()) + " instance(s) in cells of " + message_number(cell);
  // Cells above kMaxCoarseOpticalDepth (trunks: solid wood is as deep as the cell is wide) are
  // clamped to it; the alone grids clamp the same cells, so the factors mostly cancel it.
  double densest = 0;
  for (double& d : depth) {
    out.max_optical_depth = std::max(out.max_optical_depth, d);
    if (d > kMaxCoarseOpticalDepth) {
      d = kMaxCoarseOpticalDepth;
      ++out.clamped_cells;
    }
    densest = std::max(densest, d);
  }
  // One grey material, leaf and wood together by extinction: a wood-like coarse material (g = -1)
  // made the coarse forest converge 5 times slower for the same factors (docs/forest.md).
  Material& m = out.medium;
  m.name = "coarse";
  m.absorbs = sums.extinction > 0 ? sums.absorbing_share > 0.5 * sums.extinction : true;
  const double scale = densest > 0 && sums.extinction > 0 ? densest / sums.extinction : 0.0;
  // Grey: the factors are ratios of coarse light, in which the channels' small differences in
  // albedo mostly cancel, and one channel solves in a third of the time (docs/forest.md).
  double absorb = 0, scatter = 0, scatter_g = 0;
  for (int c = 0; c < kChannels; ++c) {
    absorb += sums.absorb[c] / kChannels;
    scatter += sums.scatter[c] / kChannels;
    scatter_g += sums.scatter_g[c] / kChannels;
  }
  for (int c = 0; c < kChannels; ++c) {
    m.channel[c].sigma_a = absorb * scale;
    m.channel[c].sigma_s = scatter * scale;
    m.channel[c].g = scatter > 0 ? std::clamp(scatter_g / scatter, -1.0, 1.0) : 0.0;
  }
  out.wood = m;
  for (std::size_t q = 0; q < dims.count(); ++q)
    if (depth[q] > 0) g.density[q] = static_cast<float>(std::min(1.0, depth[q] / densest));
  return out;
}

}  // namespace

const ForestModel& forest_model(const std::vector<ForestModel>& models, const std::string& name) {
  for (const ForestModel& m : models)
    if (m.spec->name == name) return m;
  throw Error(ErrorCategory::Internal, "forest: no model '" + name + "'");
}

double default_coarse_cell_size(const std::vector<ForestModel>& models, const std::vector<ForestInstance>& instances) {
  double voxel = 0, scale = 0;
  for (const ForestModel& m : models) voxel = std::max(voxel, voxel_edge(*m.grid));
  for (const ForestInstance& in : instances) scale = std::max(scale, in.scale);
  return kDefaultCoarseCellVoxels * voxel * (scale > 0 ? scale : 1.0);
}

CoarseForest build_coarse_forest(const std::vector<ForestModel>& models, const std::vector<ForestInstance>& instances,
                                 double cell, const Location& where) {
  CoarseForest out;
  out.cell_size = cell;
  out.forest = deposit(models, instances, cell, where, "the coarse forest grid");
  for (const ForestModel& m : models) {
    ForestInstance alone;
    alone.model = m.spec->name;
    out.alone.push_back(deposit(models, {alone}, cell, where, "the coarse grid of model '" + m.spec->name + "' alone"));
  }
  return out;
}

}  // namespace lblight
