// Bake outputs reopen with OpenVDB and carry the right grids, transform and metadata.
#include <catch2/catch.hpp>

#include <cmath>
#include <map>

#include "lblight/io/bake_output.h"
#include "lblight/io/vdb_io.h"
#include "tests/test_support.h"

using namespace lblight;
using namespace lblight::test;

TEST_CASE("Output .vdb holds density, brown and B grids with transform and metadata", "[io]") {
  TempDir tmp;
  const Scene scene = parse_scene(R"({"version": 1, "name": "t", "models": [
      {"name": "shrub", "density": {"type": "procedural", "shape": "plant", "resolution": 14, "size": 2.8},
       "material": "leaf", "wood_material": "bark"}],
      "lighting": {"mode": "base", "solutions": "0,1,6"},
      "solver": {"iterations": 12}})",
                                  tmp / "scene.json");
  const BakedModel baked = bake_first_model(scene, tmp / "out");
  const ModelPlan& mp = baked.model();

  const auto file = tmp / "out" / "shrub.vdb";
  REQUIRE(std::filesystem::exists(file));
  REQUIRE(std::filesystem::exists(tmp / "out" / "manifest.json"));
  const nlohmann::json info = inspect_vdb(file);
  std::map<std::string, nlohmann::json> grids;
  for (const auto& g : info["grids"]) grids[g["name"]] = g;
  std::vector<std::string> names;
  for (const auto& [name, g] : grids) names.push_back(name);
  CHECK(names == std::vector<std::string>{"B00", "B01", "B06", "brown", "density"});  // sorted
  CHECK(grids["density"]["class"] == "fog volume");
  CHECK(grids["density"]["type"] == "float");
  CHECK(grids["brown"]["type"] == "float");
  CHECK(grids["B01"]["type"] == "vec3s");
  CHECK(grids["density"]["voxel_size"][0].get<double>() == Approx(2.8 / 14));

  for (const SolutionResult& r : baked.kept) {
    const DenseGridIn g = read_vdb_grid_dense(file, r.plan.grid_name);
    CHECK(g.frame.dims == mp.lattice.dims);
    CHECK(g.frame.index_min == mp.lattice_index_min);
    for (int e = 0; e < 16; ++e) CHECK(g.frame.index_to_world[e] == Approx(mp.grid.index_to_world[e]).margin(1e-12));
    CHECK(g.metadata["lblight_iterations"] == 12);
    CHECK(g.metadata["lblight_solution"] == r.plan.index);
    CHECK(g.metadata["lblight_direction"] == nlohmann::json(r.plan.direction));
    for (int c = 0; c < 3; ++c) CHECK(g.values[c] == r.totals[c]);
  }
  // world position of lattice node (0, 0, 0) as recorded in the manifest
  const nlohmann::json manifest = nlohmann::json::parse(read_text(tmp / "out" / "manifest.json"));
  const auto origin = manifest["models"][0]["lattice"]["origin"];
  const auto o = lattice_origin_world(mp);
  for (int c = 0; c < 3; ++c) CHECK(origin[c].get<double>() == Approx(o[c]));
  CHECK(manifest["models"][0]["solutions"].size() == 3);
  CHECK(manifest["scene"]["hash"] == scene.hash);
}

TEST_CASE("Dense arrays are x fastest in OpenVDB index space", "[io]") {
  // One non-zero node at lattice (4, 0, 0) of a 5x3x2 lattice: OpenVDB must see it at index (4, 0, 0)
  // (plus index_min), whatever dense layout the I/O uses internally.
  TempDir tmp;
  DenseFrame frame{{5, 3, 2}, {10, 20, 30}, {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}};
  std::vector<float> scalar(frame.dims.count(), 0.0f);
  scalar[frame.dims.index(4, 0, 0)] = 1.0f;
  std::array<std::vector<float>, 3> rgb;
  for (auto& c : rgb) c.assign(frame.dims.count(), 0.0f);
  rgb[1][frame.dims.index(1, 2, 1)] = 2.0f;
  write_vdb(tmp / "o.vdb", frame, {{"s", &scalar, nullptr, false, {}}, {"v", nullptr, &rgb, false, {}}}, {});
  // Without lattice metadata the reader takes the active bounding box: exactly the one voxel.
  const DenseGridIn s = read_vdb_grid_dense(tmp / "o.vdb", "s");
  CHECK(s.frame.index_min == std::array<int, 3>{14, 20, 30});
  CHECK(s.frame.dims == Dims{1, 1, 1});
  const DenseGridIn v = read_vdb_grid_dense(tmp / "o.vdb", "v");
  CHECK(v.frame.index_min == std::array<int, 3>{11, 22, 31});
  CHECK(v.values[1].at(0) == 2.0f);
}
