// The coarse forest grid (lblight/scene/forest_coarse.h): optical depth kept through a
// homogeneous block at any cell size and instance scale, cells clamped where too deep, the
// alone grids of each model, and the instance transform's quarter turns exact.
#include <catch2/catch.hpp>

#include <cmath>

#include "lblight/scene/forest_coarse.h"
#include "lblight/scene/material.h"

using namespace lblight;

namespace {

// A block of n^3 voxels of edge h and density rho, voxel centres at h (i, j, k) + origin.
ModelGrid block(int n, double h, float rho, std::array<double, 3> origin = {0, 0, 0}) {
  ModelGrid g;
  g.dims = {n, n, n};
  g.index_to_world = {h, 0, 0, origin[0], 0, h, 0, origin[1], 0, 0, h, origin[2], 0, 0, 0, 1};
  g.density.assign(g.dims.count(), rho);
  g.material.assign(g.dims.count(), kMaterialMedium);
  return g;
}

ModelSpec leaf_model(const std::string& name) {
  ModelSpec s;
  s.name = name;
  s.material = *material_preset("leaf");
  s.wood_material = *material_preset("bark");
  return s;
}

// Optical depth along z through cell column (x, y) of a coarse grid: sum rho sigma_t.
double column_depth(const CoarseGrid& c, int x, int y) {
  double d = 0;
  for (int z = 0; z < c.grid.dims.nz; ++z) d += c.grid.density[c.grid.dims.index(x, y, z)] * c.medium.channel[1].sigma_t();
  return d;
}

}  // namespace

TEST_CASE("coarse cells keep the optical depth of a homogeneous block", "[forest]") {
  const ModelSpec spec = leaf_model("block");
  const double sigma_t = spec.material.channel[1].sigma_t();  // leaf: 1 per voxel in every channel
  for (const auto& [voxels_per_cell, scale] : {std::pair{2, 1.0}, std::pair{4, 1.0}, std::pair{4, 2.0}}) {
    // 16^3 voxels of edge 0.25 (x scale in the world); the block starts on a cell boundary.
    const int n = 16;
    const double h = 0.25, cell = voxels_per_cell * h * scale;
    const ModelGrid g = block(n, h, 0.1f, {0.5 * h, 0.5 * h, 0.5 * h});
    // Voxel centres at h (i + 1/2) x scale - cell / 2: cell centres at cell (i, j, k). Each voxel
    // spreads over the two cells around its centre per axis, so the block's outer cells are
    // partly filled and its inner ones (cells 1 .. n / voxels_per_cell - 2 per axis) wholly.
    const ForestInstance in{"block", {-0.5 * cell, -0.5 * cell, -0.5 * cell}, 0, scale};
    const CoarseForest c = build_coarse_forest({{&spec, &g}}, {in}, cell, {});
    INFO("voxels per cell " << voxels_per_cell << ", scale " << scale);
    const int cells = n / voxels_per_cell;
    const Dims& d = c.forest.grid.dims;
    REQUIRE(d.nx == cells + 2);  // the inner cells and one partly filled cell either side
    // Fine optical depth through the block along z: n voxels x rho sigma_t, whatever the scale
    // (a scaled instance is the same lattice, larger in the world).
    const double fine = n * 0.1 * sigma_t;
    double sum = 0;
    int inner = 0;
    for (int y = 0; y < d.ny; ++y)
      for (int x = 0; x < d.nx; ++x) {
        const double depth = column_depth(c.forest, x, y);
        sum += depth;
        if (x < 2 || y < 2 || x >= d.nx - 2 || y >= d.ny - 2) continue;
        ++inner;
        CHECK(depth == Approx(fine).epsilon(1e-6));
      }
    CHECK(inner == (cells - 2) * (cells - 2));
    // All of the block's extinction is in the grid: its columns hold `cells^2` columns' depth.
    CHECK(sum == Approx(fine * cells * cells).epsilon(1e-6));
    CHECK(c.forest.clamped_cells == 0);
    CHECK(c.forest.max_optical_depth == Approx(0.1 * sigma_t * voxels_per_cell).epsilon(1e-6));
    // The alone grid (the model at the origin, scale 1: other cell boundaries, up to 8 voxels per
    // cell, still below the clamp at density 0.1) holds the same
    // optical depth summed over its cells, over scale^2 (the scaled block covers scale^2 as many
    // columns).
    REQUIRE(c.alone.size() == 1);
    double forest_sum = 0, alone_sum = 0;
    for (float v : c.forest.grid.density) forest_sum += v * c.forest.medium.channel[0].sigma_t();
    for (float v : c.alone[0].grid.density) alone_sum += v * c.alone[0].medium.channel[0].sigma_t();
    CHECK(alone_sum * scale * scale == Approx(forest_sum).epsilon(1e-6));
  }
}

TEST_CASE("an instance's coarse depth moves with it by fractions of a cell", "[forest]") {
  // A block shifted by part of a cell moves its coarse depth's centroid by exactly that part
  // (each voxel is shared between the cells around its centre), so the coarse light of an
  // instance and of its model alone differ by no more than the offset between them.
  const ModelSpec spec = leaf_model("block");
  const ModelGrid g = block(3, 0.25, 0.2f, {0.125, 0.125, 0.125});  // voxel centres 0.125 .. 0.625
  for (double shift : {0.0, 0.1, 0.25, 0.4, 0.7}) {
    const CoarseForest c = build_coarse_forest({{&spec, &g}}, {{"block", {shift, 0, 0}, 0, 1}}, 1.0, {});
    const Dims& d = c.forest.grid.dims;
    double sum = 0, moment = 0;
    for (int z = 0; z < d.nz; ++z)
      for (int y = 0; y < d.ny; ++y)
        for (int x = 0; x < d.nx; ++x) {
          const double v = c.forest.grid.density[d.index(x, y, z)];
          sum += v;
          moment += v * (x + c.forest.grid.index_min[0]);  // cell x sits at world x (cell size 1)
        }
    INFO("shift " << shift);
    CHECK(moment / sum == Approx(0.375 + shift).epsilon(1e-6));  // densities are floats
  }
}

TEST_CASE("coarse cells deeper than the stability margin are clamped and counted", "[forest]") {
  const ModelSpec spec = leaf_model("solid");
  // 16^3 voxels of edge 0.25, density 0.3, in cells of 1: per axis the cells around the block hold
  // 0.5, 3.5, 4, 4, 3.5 and 0.5 voxels' worth, each voxel rho sigma_t (0.25 / 1)^2 = 0.3 / 16.
  // The inner 8 cells (1.2) and the 24 next to them on one axis (1.05) are too deep; nearest-cell
  // deposit would give 64 cells of 1.2.
  const double rho = 0.3;
  const ModelGrid g = block(16, 0.25, static_cast<float>(rho), {0.125, 0.125, 0.125});
  const CoarseForest c = build_coarse_forest({{&spec, &g}}, {{"solid", {-0.5, -0.5, -0.5}, 0, 1}}, 1.0, {});
  CHECK(c.forest.max_optical_depth == Approx(64 * rho / 16));  // 4 x 4 x 4 voxels in the inner cells
  const double per_axis[6] = {0.5, 3.5, 4, 4, 3.5, 0.5};
  int deep = 0;
  for (double a : per_axis)
    for (double b : per_axis)
      for (double e : per_axis) deep += a * b * e * rho / 16 > kMaxCoarseOpticalDepth ? 1 : 0;
  CHECK(deep == 32);
  CHECK(c.forest.clamped_cells == deep);
  double rho_sigma = 0;
  for (float d : c.forest.grid.density) rho_sigma = std::max(rho_sigma, d * c.forest.medium.channel[0].sigma_t());
  CHECK(rho_sigma == Approx(kMaxCoarseOpticalDepth));
}

TEST_CASE("two instances add their optical depth where they overlap, and the material is grey", "[forest]") {
  const ModelSpec spec = leaf_model("block");
  const ModelGrid g = block(4, 0.25, 0.1f, {0.125, 0.125, 0.125});
  const CoarseForest one = build_coarse_forest({{&spec, &g}}, {{"block", {0, 0, 0}, 0, 1}}, 0.5, {});
  const CoarseForest two = build_coarse_forest({{&spec, &g}}, {{"block", {0, 0, 0}, 0, 1}, {"block", {0, 0, 0}, 0, 1}}, 0.5, {});
  CHECK(two.forest.max_optical_depth == Approx(2 * one.forest.max_optical_depth));
  for (int c = 1; c < 3; ++c) {
    CHECK(two.forest.medium.channel[c].sigma_a == two.forest.medium.channel[0].sigma_a);
    CHECK(two.forest.medium.channel[c].g == two.forest.medium.channel[0].g);
  }
}

TEST_CASE("instance transforms: quarter turns are exact permutations, other yaws rotate", "[forest]") {
  const InstanceTransform t({"m", {1, 2, 3}, 90, 2});
  const Vec3d w = t.to_world({1, 0, 0.5});
  CHECK(w.x == 1.0);
  CHECK(w.y == 4.0);
  CHECK(w.z == 4.0);
  const Vec3d back = t.to_model(w);
  CHECK(back.x == 1.0);
  CHECK(back.y == 0.0);
  CHECK(back.z == 0.5);
  const Vec3d d = t.direction_to_model({0, 1, 0});  // world +y is the model's +x after a quarter turn
  CHECK(d.x == 1.0);
  CHECK(d.y == 0.0);
  const InstanceTransform u({"m", {0, 0, 0}, 30, 1});
  const Vec3d r = u.to_world({1, 0, 0});
  CHECK(r.x == Approx(std::cos(M_PI / 6)));
  CHECK(r.y == Approx(0.5));
  const Vec3d r2 = u.to_model(r);
  CHECK(r2.x == Approx(1.0));
  CHECK(std::fabs(r2.y) < 1e-12);
}
