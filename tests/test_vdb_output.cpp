// Bake outputs reopen with OpenVDB and carry the right grids, transform and metadata.
#include <catch2/catch.hpp>

#include <cmath>
#include <map>

#include "backends/openmp/openmp_backend.h"
#include "lblight/io/bake_output.h"
#include "lblight/io/vdb_io.h"
#include "lblight/solve/bake.h"
#include "tests/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {
class Collect final : public BakeObserver {
 public:
  explicit Collect(BakeOutput& out) : out_(out) {}
  void solution_done(const ModelPlan& mp, SolutionResult& r) override {
    kept.push_back(r);  // copy before the output takes the totals
    out_.add(mp, r);
  }
  std::vector<SolutionResult> kept;

 private:
  BakeOutput& out_;
};
}  // namespace

TEST_CASE("Output .vdb holds density, brown and B grids with transform and metadata", "[io]") {
  TempDir tmp;
  const Scene scene = parse_scene(R"({"version": 1, "name": "t", "models": [
      {"name": "shrub", "density": {"type": "procedural", "shape": "plant", "resolution": 14, "size": 2.8},
       "material": "leaf", "wood_material": "bark"}],
      "lighting": {"mode": "base", "solutions": "0,1,6"},
      "solver": {"iterations": 12}})",
                                  tmp / "scene.json");
  const BakePlan plan = make_plan(scene);
  const ModelPlan& mp = plan.models.at(0);
  auto backend = make_openmp_backend(0);
  BakeOutput out(plan, tmp / "out", {"test", "cpu", backend->description(), Precision::Float32});
  Collect collect(out);
  bake_model(mp, *backend, {}, collect);
  out.finish_model(mp);
  out.commit(1.0);

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

  for (const SolutionResult& r : collect.kept) {
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
