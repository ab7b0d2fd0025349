// Relighting one baked model for a sun (`lblight relight`, docs/output-format.md): the light of a
// static bake assembled from the base solutions, light = s (w_a B_a + w_b B_b + w_c B_c) + a B00
// with the weights of the sun's direction on the 32-face polyhedron (docs/model.md sec. 4.1), as
// the .lbh reader does per sample. The same numbers a static bake of that sun gives, up to float
// rounding (tests/cli/test_relight_cli.cpp).
#pragma once

#include <array>
#include <filesystem>
#include <utility>
#include <vector>

#include "lblight/core/run_context.h"
#include "lblight/lattice/dense_grid.h"
#include "lblight/lattice/sun.h"

namespace lblight {

struct RelightRequest {
  Vec3d toward_sun{0, 0, 1};
  double intensity = 1.0;  // s
  double ambient = 0.0;    // a
};

struct RelitModel {
  DenseFrame frame;                            // the bake's lattice box
  std::array<std::vector<float>, 3> light;     // 0 outside the occupied nodes and their neighbours
  std::vector<float> density;                  // on the same frame
  std::vector<std::pair<int, double>> weights; // (base solution, weight) used
};

// Reads the base-solution grids of one bake .vdb. Error(InvalidInput) naming the file and the
// grid when the bake left out a solution this sun needs (a sun outside the scene's sun_range, or
// an instance rotation it did not declare) or holds a static bake.
RelitModel relight_model(const std::filesystem::path& vdb, const RelightRequest& request, const RunContext& ctx = {});

}  // namespace lblight
