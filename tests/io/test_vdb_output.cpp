// Bake outputs reopen with OpenVDB and carry the right grids, transform and metadata; density
// inputs read from .vdb keep to the documented rules (background, wood grid, transform).
#include <catch2/catch.hpp>

#include <cmath>
#include <map>

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include "lblight/pipeline/bake_output.h"
#include "lblight/io/vdb_io.h"
#include "lblight/scene/load_model.h"
#include "tests/support/expect_error.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {
// A 4x4x4 float grid filled with `value`, written by OpenVDB itself (for inputs lblight's own
// writer never makes: another background, another transform).
openvdb::FloatGrid::Ptr cube_grid(const std::string& name, float value, float background, double voxel) {
  openvdb::initialize();
  auto g = openvdb::FloatGrid::create(background);
  g->setName(name);
  g->setTransform(openvdb::math::Transform::createLinearTransform(voxel));
  g->fill(openvdb::CoordBBox(openvdb::Coord(0), openvdb::Coord(3)), value, true);
  return g;
}
void write_grids(const std::filesystem::path& file, const openvdb::GridPtrVec& grids) {
  openvdb::io::File(file.string()).write(grids);
}
// The density grid of a scene whose one model reads `wood_grid` (if any) beside "density" from grid.vdb.
ModelGrid load_vdb_model(const TempDir& tmp, const std::string& wood_grid = "") {
  const Scene scene = parse_scene(R"({"version": 1, "models": [{"name": "m", "density": {"type": "vdb",
      "path": "grid.vdb")" + (wood_grid.empty() ? std::string() : R"(, "wood_grid": ")" + wood_grid + "\"") +
                                      R"(}, "material": "cloud"}]})",
                                  tmp / "s.json");
  return load_model_grid(scene.models.at(0), scene);
}
}  // namespace

TEST_CASE("Output .vdb holds density, brown and B grids with transform and metadata", "[io]") {
  TempDir tmp;
  const Scene scene = parse_scene(R"({"version": 1, "name": "t", "models": [
      {"name": "shrub", "density": {"type": "procedural", "shape": "plant", "resolution": 14, "size": 2.8},
       "material": "leaf", "wood_material": "bark"}],
      "lighting": {"mode": "base", "solutions": "0,1,6"},
      "solver": {"iterations": 12}, "output": {"full_box": true}})",
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
  // density and brown read back: the lattice's density, and 1 exactly on wood nodes with density
  const DenseGridIn density = read_vdb_grid_dense(file, "density");
  const DenseGridIn brown = read_vdb_grid_dense(file, "brown");
  REQUIRE(density.frame.dims == mp.lattice.dims);
  REQUIRE(brown.frame.dims == mp.lattice.dims);
  CHECK(density.values[0] == mp.lattice.density);
  std::size_t wood = 0, brown_ones = 0, brown_wrong = 0;
  for (std::size_t i = 0; i < mp.lattice.density.size(); ++i) {
    const bool is_wood = mp.lattice.material[i] == 1 && mp.lattice.density[i] > 0.0f;
    wood += is_wood;
    brown_ones += brown.values[0][i] == 1.0f;
    brown_wrong += brown.values[0][i] != (is_wood ? 1.0f : 0.0f);
  }
  CHECK(wood > 0);
  CHECK(brown_ones == wood);
  CHECK(brown_wrong == 0);
  // world position of lattice node (0, 0, 0) in the manifest: the grid's own transform (as
  // OpenVDB reads it back) applied to the node's index coordinates
  const nlohmann::json manifest = nlohmann::json::parse(read_text(tmp / "out" / "manifest.json"));
  const auto origin = manifest["models"][0]["lattice"]["origin"];
  const auto& m = density.frame.index_to_world;
  const auto& imin = density.frame.index_min;
  for (int r = 0; r < 3; ++r) {
    const double want = m[r * 4] * imin[0] + m[r * 4 + 1] * imin[1] + m[r * 4 + 2] * imin[2] + m[r * 4 + 3];
    CHECK(origin[r].get<double>() == Approx(want).margin(1e-12));
  }
  CHECK(std::abs(m[3]) + std::abs(m[7]) + std::abs(m[11]) > 0);  // a translated frame: the term matters
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

// Static lighting through the whole scene path (angles or vector, intensity, ambient) against the
// base solutions of the same model, by linearity: the sun straight up travels along lattice
// direction 6 (0, 0, -1); elevation 0 / azimuth 90 points toward +y, so its light travels along
// direction 4 (0, -1, 0) (docs/output-format.md's table).
TEST_CASE("Static lighting equals intensity x B_j + ambient x B00 for suns along lattice directions", "[io][sun]") {
  TempDir tmp;
  const std::string model = R"("models": [{"name": "m", "density": {"type": "procedural", "shape": "plant",
      "resolution": 12}, "material": "leaf", "wood_material": "bark"}], "solver": {"iterations": 30})";
  const auto bake = [&](const std::string& name, const std::string& lighting) {
    const Scene scene = parse_scene(R"({"version": 1, )" + model + R"(, "lighting": )" + lighting + "}",
                                    tmp / (name + ".json"));
    BakedModel b = bake_first_model(scene, tmp / name);
    std::map<std::string, std::array<std::vector<float>, 3>> out;
    for (const SolutionResult& r : b.kept) out[r.plan.grid_name] = r.totals;
    return out;
  };
  auto base = bake("base", R"({"mode": "base", "solutions": "0,4,6", "ambient_from_sum": false})");
  struct Case {
    std::string lighting;
    std::string grid;
    double intensity, ambient;
  };
  for (const Case& c : {Case{R"({"mode": "static", "sun": {"direction": [0, 0, 3]}, "intensity": 2, "ambient": 0.5})",
                             "B06", 2.0, 0.5},
                        Case{R"({"mode": "static", "sun": {"elevation": 0, "azimuth": 90}, "intensity": 1.5})", "B04",
                             1.5, 0.0},
                        Case{R"({"mode": "static", "sun": {"elevation": 90, "azimuth": 17}, "ambient": 0.25})", "B06",
                             1.0, 0.25}}) {
    INFO(c.lighting);
    auto stat = bake("static", c.lighting);
    REQUIRE(stat.count("light") == 1);
    for (int ch = 0; ch < 3; ++ch) {
      std::vector<double> want(base["B00"][ch].size());
      for (std::size_t i = 0; i < want.size(); ++i)
        want[i] = c.intensity * base[c.grid][ch][i] + c.ambient * base["B00"][ch][i];
      CHECK(peak_magnitude(want) > 0);
      CHECK(max_relative_difference(want, stat["light"][ch], 1e-3 * peak_magnitude(want)) < 1e-5);
    }
    std::filesystem::remove_all(tmp / "static");
  }
}

TEST_CASE("A density grid's rotated anisotropic transform gives the manifest's voxel size per index axis", "[io]") {
  // voxel_size is the world length of one step along each index axis: the norm of the transform's
  // column, which only differs from its row's when the grid is rotated and not uniformly scaled
  TempDir tmp;
  const double c = std::cos(M_PI / 6), s = std::sin(M_PI / 6);
  const DenseFrame frame{{4, 4, 4}, {0, 0, 0}, {c * 0.1, -s * 0.2, 0, 1, s * 0.1, c * 0.2, 0, 2, 0, 0, 0.3, 3, 0, 0, 0, 1}};
  const std::vector<float> density(frame.dims.count(), 0.5f);
  write_density_vdb(tmp / "grid.vdb", frame, density);
  const Scene scene = parse_scene(R"({"version": 1, "models": [{"name": "m", "density": {"type": "vdb",
      "path": "grid.vdb"}, "material": "cloud"}], "lighting": {"solutions": "1"}, "solver": {"iterations": 2}})",
                                  tmp / "s.json");
  bake_first_model(scene, tmp / "out");
  const nlohmann::json manifest = nlohmann::json::parse(read_text(tmp / "out" / "manifest.json"));
  const auto vs = manifest["models"][0]["lattice"]["voxel_size"];
  REQUIRE(vs.size() == 3);
  CHECK(vs[0].get<double>() == Approx(0.1));
  CHECK(vs[1].get<double>() == Approx(0.2));
  CHECK(vs[2].get<double>() == Approx(0.3));
}

TEST_CASE("A density grid must have background 0", "[io][validate]") {
  // inactive voxels read as the background: anything but empty space there is refused
  TempDir tmp;
  write_grids(tmp / "grid.vdb", {cube_grid("density", 0.5f, 0.25f, 0.1)});
  expect_invalid_input([&] { load_vdb_model(tmp); }, "background");
  write_grids(tmp / "grid.vdb", {cube_grid("density", 0.5f, 0.0f, 0.1)});
  CHECK(load_vdb_model(tmp).occupied_nodes() == 64);
}

TEST_CASE("Wood grid voxels above 0.5 are wood and those at or below are not", "[io]") {
  // docs/scene-format.md: a float wood grid marks wood where its value is > 0.5
  TempDir tmp;
  const DenseFrame frame = cube_frame(4, 0.1);
  const std::vector<float> density(64, 0.5f);
  std::vector<float> wood(64, 0.0f);
  for (std::size_t i = 0; i < 16; ++i) wood[i] = 0.3f;
  for (std::size_t i = 16; i < 32; ++i) wood[i] = 0.5f;
  for (std::size_t i = 48; i < 64; ++i) wood[i] = 1.0f;
  write_vdb(tmp / "grid.vdb", frame, {{"density", &density, nullptr, true, {}}, {"wood", &wood, nullptr, false, {}}},
            nlohmann::json::object());
  const ModelGrid g = load_vdb_model(tmp, "wood");
  REQUIRE(g.dims == frame.dims);
  for (std::size_t i = 0; i < 64; ++i) {
    INFO("node " << i << ", wood grid value " << wood[i]);
    CHECK((g.material[i] == 1) == (wood[i] > 0.5f));
  }
  CHECK(g.wood_nodes() == 16);
}

TEST_CASE("A wood grid must share the density grid's transform", "[io][validate]") {
  // voxels of differently placed grids do not correspond: refused rather than misread
  TempDir tmp;
  write_grids(tmp / "grid.vdb", {cube_grid("density", 0.5f, 0.0f, 0.1), cube_grid("wood", 1.0f, 0.0f, 0.05)});
  expect_invalid_input([&] { load_vdb_model(tmp, "wood"); }, "transform");
  write_grids(tmp / "grid.vdb", {cube_grid("density", 0.5f, 0.0f, 0.1), cube_grid("wood", 1.0f, 0.0f, 0.1)});
  CHECK(load_vdb_model(tmp, "wood").wood_nodes() == 64);
}

TEST_CASE("Output light grids are active only on occupied nodes and their neighbours, never the boundary layer", "[io]") {
  TempDir tmp;
  const std::string scene = R"({"version": 1, "name": "t", "models": [
      {"name": "shrub", "density": {"type": "procedural", "shape": "plant", "resolution": 14, "size": 2.8},
       "material": "leaf", "wood_material": "bark"}],
      "lighting": {"mode": "base", "solutions": "0,1,6"}, "solver": {"iterations": 12})";
  const BakedModel masked = bake_first_model(parse_scene(scene + "}", tmp / "a.json"), tmp / "masked");
  const BakedModel full = bake_first_model(parse_scene(scene + R"(, "output": {"full_box": true}})", tmp / "b.json"), tmp / "full");
  const DenseGridIn m = read_vdb_grid_dense(tmp / "masked" / "shrub.vdb", "B06");
  const DenseGridIn f = read_vdb_grid_dense(tmp / "full" / "shrub.vdb", "B06");
  const DenseGridIn rho = read_vdb_grid_dense(tmp / "masked" / "shrub.vdb", "density");
  REQUIRE(m.frame == f.frame);
  const Dims& d = m.frame.dims;
  std::size_t kept = 0, occupied = 0;
  for (int z = 0; z < d.nz; ++z)
    for (int y = 0; y < d.ny; ++y)
      for (int x = 0; x < d.nx; ++x) {
        const std::size_t i = d.index(x, y, z);
        bool near = false;
        for (int dz = -1; dz <= 1; ++dz)
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int a = x + dx, b = y + dy, c = z + dz;
              near = near || (a >= 0 && b >= 0 && c >= 0 && a < d.nx && b < d.ny && c < d.nz &&
                              rho.values[0][d.index(a, b, c)] > 0.0f);
            }
        near = near && !d.is_boundary(x, y, z);
        occupied += rho.values[0][i] > 0.0f;
        for (int c = 0; c < 3; ++c) {
          if (near) REQUIRE(m.values[c][i] == f.values[c][i]);
          else REQUIRE(m.values[c][i] == 0.0f);
        }
        kept += near;
      }
  const nlohmann::json info = inspect_vdb(tmp / "masked" / "shrub.vdb");
  for (const auto& g : info["grids"])
    if (g["name"] == "B06") {
      CHECK(g["active_voxels"].get<std::size_t>() <= kept);
      CHECK(g["metadata"]["lblight_units"].get<std::string>().find("open-air") != std::string::npos);
    }
  INFO("occupied " << occupied << ", kept " << kept << " of " << d.count());
  CHECK(kept < d.count() / 2);
}

TEST_CASE("output.half stores the light grids as 16-bit floats, the rounding error in the manifest", "[io]") {
  TempDir tmp;
  const std::string scene = R"({"version": 1, "name": "t", "models": [
      {"name": "shrub", "density": {"type": "procedural", "shape": "plant", "resolution": 14, "size": 2.8},
       "material": "leaf", "wood_material": "bark"}],
      "lighting": {"mode": "base", "solutions": "0,1,6"}, "solver": {"iterations": 12})";
  bake_first_model(parse_scene(scene + R"(, "output": {"half": true}})", tmp / "a.json"), tmp / "half");
  bake_first_model(parse_scene(scene + "}", tmp / "b.json"), tmp / "float");
  const DenseGridIn h = read_vdb_grid_dense(tmp / "half" / "shrub.vdb", "B06");
  const DenseGridIn f = read_vdb_grid_dense(tmp / "float" / "shrub.vdb", "B06");
  double err = 0, peak = 0;
  bool rounded = false;
  for (int c = 0; c < 3; ++c)
    for (std::size_t i = 0; i < f.values[c].size(); ++i) {
      err = std::max(err, static_cast<double>(std::fabs(h.values[c][i] - f.values[c][i])));
      peak = std::max(peak, static_cast<double>(std::fabs(f.values[c][i])));
      rounded = rounded || h.values[c][i] != f.values[c][i];
    }
  CHECK(rounded);                 // really stored as half
  CHECK(err <= 1.0e-3 * peak);    // half: 11 significant bits
  const auto manifest = nlohmann::json::parse(read_text(tmp / "half" / "manifest.json"));
  const auto& sols = manifest["models"][0]["solutions"];
  for (const auto& s : sols) {
    REQUIRE(s.contains("half_error_max"));
    CHECK(s["half_error_max"].get<double>() <= 1e-3);
  }
  CHECK(manifest["units"].get<std::string>().find("open-air") != std::string::npos);
  CHECK(std::filesystem::file_size(tmp / "half" / "shrub.vdb") < std::filesystem::file_size(tmp / "float" / "shrub.vdb"));
}
