// lblight simulate and the "gas" density source: frames written as .vdb (density, temperature,
// velocity) with simulation.json, the smoke rising frame by frame, a bake lighting the chosen
// frame, unstable settings refused by JSON pointer before anything is written, and every frame
// lit (--light), warm-started from the previous one.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <set>

#include <nlohmann/json.hpp>

#include "lblight/io/vdb_io.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {

std::string scene(const std::string& gas_extra) {
  return R"({"version": 1, "models": [{"name": "plume", "density": {"type": "gas", "resolution": [12, 12, 24],
    "size": 1.0, "tau": 0.6, "buoyancy": 1e-4, "frames": 3, "steps_per_frame": 40,
    "inlet": {"center": [0, 0], "radius": 0.15, "speed": 0.05, "temperature": 40}, "density_scale": 0.5)" +
         gas_extra + R"(}, "material": "cloud"}],
    "lighting": {"mode": "static", "sun": {"elevation": 40, "azimuth": 0}}, "solver": {"tolerance": 1e-3}})";
}

}  // namespace

TEST_CASE("simulate: every frame as a .vdb with density, temperature and velocity, the smoke rising", "[cli][fluid]") {
  TempDir tmp;
  write_text(tmp / "gas.json", scene(""));
  const CliResult r = run_cli("simulate gas.json -o sim -q", tmp.path());
  INFO(r.out << r.err);
  REQUIRE(r.exit_code == 0);
  const nlohmann::json rec = nlohmann::json::parse(read_text(tmp / "sim" / "simulation.json"));
  REQUIRE(rec["frames"].size() == 3);
  double previous = 0;
  for (int f = 1; f <= 3; ++f) {
    const nlohmann::json& e = rec["frames"][static_cast<std::size_t>(f - 1)];
    CHECK(e["frame"] == f);
    CHECK(e["steps"] == 40 * f);
    CHECK(e["smoke_sum"].get<double>() > previous);  // the inlet keeps feeding smoke
    previous = e["smoke_sum"].get<double>();
    const nlohmann::json info = inspect_vdb(tmp / "sim" / e["file"].get<std::string>());
    std::set<std::string> names;
    for (const auto& g : info["grids"]) names.insert(g["name"].get<std::string>());
    CHECK(names == std::set<std::string>{"density", "temperature", "velocity"});
  }
  // The smoke's centre rises from frame 1 to 3, and the gas above the inlet is warm and rising.
  auto centroid = [&](int f) {
    const DenseGridIn d = read_vdb_grid_dense(tmp / "sim" / ("plume.000" + std::to_string(f) + ".vdb"), "density");
    double w = 0, wz = 0;
    for (int z = 0; z < d.frame.dims.nz; ++z)
      for (int y = 0; y < d.frame.dims.ny; ++y)
        for (int x = 0; x < d.frame.dims.nx; ++x) {
          const double v = d.values[0][d.frame.dims.index(x, y, z)];
          w += v;
          wz += v * (z + d.frame.index_min[2]);
        }
    return wz / w;
  };
  CHECK(centroid(3) > centroid(1) + 1.0);
  const DenseGridIn t = read_vdb_grid_dense(tmp / "sim" / "plume.0003.vdb", "temperature");
  const DenseGridIn u = read_vdb_grid_dense(tmp / "sim" / "plume.0003.vdb", "velocity");
  const std::size_t above_inlet = t.frame.dims.index(6 - t.frame.index_min[0], 6 - t.frame.index_min[1], 3 - t.frame.index_min[2]);
  CHECK(t.values[0][above_inlet] > 30.0);
  CHECK(u.values[2][above_inlet] > 0.0f);
  // Run again into the same folder: replaced, as a bake is.
  CHECK(run_cli("simulate gas.json -o sim -q --frames 1", tmp.path()).exit_code == 0);
  CHECK_FALSE(std::filesystem::exists(tmp.path() / "sim" / "plume.0002.vdb"));
}

TEST_CASE("simulate: a bake lights the chosen frame of the gas", "[cli][fluid]") {
  TempDir tmp;
  write_text(tmp / "gas.json", scene(R"(, "frame": 2)"));
  const CliResult r = run_cli("bake gas.json -o bake --backend cpu -q", tmp.path());
  INFO(r.out << r.err);
  REQUIRE(r.exit_code == 0);
  const nlohmann::json m = nlohmann::json::parse(read_text(tmp / "bake" / "manifest.json"));
  CHECK(m["models"][0]["source"].get<std::string>().find("frame 2 of 3") != std::string::npos);
  CHECK(m["models"][0]["occupied_nodes"].get<long long>() > 20);
  // validate plans that frame too, and says it simulated to get it.
  const CliResult v = run_cli("validate gas.json --backend cpu --no-timing", tmp.path());
  CHECK(v.exit_code == 0);
  CHECK(v.out.find("frame 2 of 3") != std::string::npos);
  CHECK(v.out.find("ran the gas simulation up to this frame") != std::string::npos);
}

TEST_CASE("simulate: unstable or unusable gas settings are refused by field, with nothing written", "[cli][fluid]") {
  TempDir tmp;
  const std::pair<std::string, std::string> cases[] = {
      {R"(, "tau": 0.5)", "/models/0/density/tau"},
      {R"(, "frame": 9)", "/models/0/density/frame"},
      {R"(, "resolution": [12, 2, 24])", "/models/0/density/resolution/1"},
  };
  for (const auto& [extra, pointer] : cases) {
    std::string text = scene(extra);
    // "tau" and "resolution" appear twice: the parser refuses duplicates, so replace the first.
    if (extra.find("\"tau\"") != std::string::npos) text.replace(text.find(R"("tau": 0.6, )"), 12, "");
    if (extra.find("\"resolution\"") != std::string::npos)
      text.replace(text.find(R"("resolution": [12, 12, 24],)"), 27, "");
    write_text(tmp / "bad.json", text);
    const CliResult r = run_cli("simulate bad.json -o out -q", tmp.path());
    INFO(extra << ": " << r.err);
    CHECK(r.exit_code == 2);
    CHECK(r.err.find(pointer) != std::string::npos);
    CHECK_FALSE(std::filesystem::exists(tmp.path() / "out"));
  }
  // The inlet faster than Mach 0.3, and an inlet off the floor.
  std::string fast = scene("");
  fast.replace(fast.find(R"("speed": 0.05)"), 13, R"("speed": 0.2)");
  write_text(tmp / "fast.json", fast);
  const CliResult f = run_cli("simulate fast.json -o out -q", tmp.path());
  CHECK(f.exit_code == 2);
  CHECK(f.err.find("/models/0/density/inlet/speed") != std::string::npos);
  std::string off = scene("");
  off.replace(off.find(R"("center": [0, 0])"), 16, R"("center": [5, 5])");
  write_text(tmp / "off.json", off);
  const CliResult o = run_cli("simulate off.json -o out -q", tmp.path());
  CHECK(o.exit_code == 2);
  CHECK(o.err.find("covers no node of the floor") != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(tmp.path() / "out"));
}

TEST_CASE("simulate: a mesh obstacle is solid for the gas, and one outside the box is refused", "[cli][fluid]") {
  TempDir tmp;
  std::filesystem::copy_file(std::filesystem::path(LBLIGHT_SOURCE_DIR) / "configs" / "meshes" / "bush.obj",
                             tmp.path() / "bush.obj");
  write_text(tmp / "gas.json",
             scene(R"(, "obstacles": [{"path": "bush.obj", "position": [0.2, 0, 0], "scale": 0.2}])"));
  const CliResult r = run_cli("simulate gas.json -o sim -q", tmp.path());
  INFO(r.out << r.err);
  REQUIRE(r.exit_code == 0);
  const DenseGridIn obstacle = read_vdb_grid_dense(tmp / "sim" / "plume.0003.vdb", "obstacle");
  const DenseGridIn smoke = read_vdb_grid_dense(tmp / "sim" / "plume.0003.vdb", "density");
  // Each grid's box is that of its own non-zero values: compare by index coordinate.
  std::size_t solid = 0;
  double inside = 0;
  const Dims& od = obstacle.frame.dims;
  const Dims& sd = smoke.frame.dims;
  for (int z = 0; z < od.nz; ++z)
    for (int y = 0; y < od.ny; ++y)
      for (int x = 0; x < od.nx; ++x) {
        if (!(obstacle.values[0][od.index(x, y, z)] > 0.5f)) continue;
        ++solid;
        const int i = x + obstacle.frame.index_min[0] - smoke.frame.index_min[0];
        const int j = y + obstacle.frame.index_min[1] - smoke.frame.index_min[1];
        const int k = z + obstacle.frame.index_min[2] - smoke.frame.index_min[2];
        if (i >= 0 && j >= 0 && k >= 0 && i < sd.nx && j < sd.ny && k < sd.nz) inside += smoke.values[0][sd.index(i, j, k)];
      }
  CHECK(obstacle.frame.index_to_world == smoke.frame.index_to_world);
  CHECK(solid > 10);
  CHECK(inside == 0.0);
  // The bush stands over part of the inlet and in the plume's way: less smoke gets in and up
  // than without it.
  write_text(tmp / "open.json", scene(""));
  REQUIRE(run_cli("simulate open.json -o open -q", tmp.path()).exit_code == 0);
  const auto total = [&](const char* folder) {
    return nlohmann::json::parse(read_text(tmp / folder / "simulation.json"))["frames"][2]["smoke_sum"].get<double>();
  };
  INFO("smoke with the bush " << total("sim") << ", without " << total("open"));
  CHECK(total("sim") < 0.99 * total("open"));  // measured: 257.7 against 264.9
  write_text(tmp / "far.json",
             scene(R"(, "obstacles": [{"path": "bush.obj", "position": [50, 0, 0], "scale": 0.2}])"));
  const CliResult far = run_cli("simulate far.json -o far -q", tmp.path());
  CHECK(far.exit_code == 2);
  CHECK(far.err.find("/models/0/density/obstacles/0") != std::string::npos);
}

TEST_CASE("simulate --light: every frame lit in its own file, warm frames in fewer steps, a frame renders",
          "[cli][fluid][warm]") {
  TempDir tmp;
  // Thin grey smoke, as configs/chimney.json lights (the shared scene's cloud would need thousands of steps).
  std::string text = scene("");
  text.replace(text.find(R"("material": "cloud")"), 19,
               R"("material": {"name": "smoke", "sigma_a": 0.1, "sigma_s": 0.9, "g": 0.3, "absorb": true})");
  write_text(tmp / "gas.json", text);
  const CliResult r = run_cli("simulate gas.json -o lit --light --backend cpu -q", tmp.path());
  INFO(r.out << r.err);
  REQUIRE(r.exit_code == 0);
  // One model per frame in the manifest, named as its file; the frames after the first start warm.
  const nlohmann::json m = nlohmann::json::parse(read_text(tmp / "lit" / "manifest.json"));
  const nlohmann::json rec = nlohmann::json::parse(read_text(tmp / "lit" / "simulation.json"));
  REQUIRE(m["models"].size() == 3);
  REQUIRE(rec["frames"].size() == 3);
  for (int f = 1; f <= 3; ++f) {
    const nlohmann::json& model = m["models"][static_cast<std::size_t>(f - 1)];
    const std::string name = "plume.000" + std::to_string(f);
    CHECK(model["name"] == name);
    CHECK(model["file"] == name + ".vdb");
    CHECK(model["frame"] == f);
    CHECK(model["solutions"][0].value("warm_start", false) == (f > 1));
    // The whole gas box every frame (never cropped): the warm start maps node to node.
    CHECK(model["lattice"]["dims"] == nlohmann::json::array({14, 14, 26}));
    const nlohmann::json info = inspect_vdb(tmp / "lit" / (name + ".vdb"));
    std::set<std::string> names;
    for (const auto& g : info["grids"]) names.insert(g["name"].get<std::string>());
    CHECK(names == std::set<std::string>{"density", "light", "light_flux_r", "light_flux_g", "light_flux_b", "temperature",
                                         "velocity"});
    CHECK(info["file_metadata"]["lblight_frame"] == f);
  }
  const auto steps = [&](const char* folder, int f) {
    return nlohmann::json::parse(read_text(tmp / folder / "simulation.json"))["frames"][f - 1]["light"]["steps"].get<int>();
  };
  INFO("light steps per frame: " << steps("lit", 1) << ", " << steps("lit", 2) << ", " << steps("lit", 3));
  CHECK(steps("lit", 3) < steps("lit", 1));
  // Each frame from zero: the same light within the tolerance (1e-3), in more steps.
  REQUIRE(run_cli("simulate gas.json -o cold --light --cold --backend cpu -q", tmp.path()).exit_code == 0);
  CHECK(steps("cold", 3) > steps("lit", 3));
  const DenseGridIn warm = read_vdb_grid_dense(tmp / "lit" / "plume.0003.vdb", "light");
  const DenseGridIn cold = read_vdb_grid_dense(tmp / "cold" / "plume.0003.vdb", "light");
  REQUIRE(warm.frame.dims == cold.frame.dims);
  double diff = 0, norm = 0;
  for (int c = 0; c < 3; ++c)
    for (std::size_t i = 0; i < cold.values[c].size(); ++i) {
      diff += std::pow(warm.values[c][i] - cold.values[c][i], 2.0);
      norm += std::pow(cold.values[c][i], 2.0);
    }
  CHECK(std::sqrt(diff / norm) < 2e-3);
  // A frame renders with the scene's sun, its material from the manifest.
  const CliResult img = run_cli("render lit/plume.0003.vdb --sun-elevation 40 --sun-azimuth 0 --orbit front --size 24x32 -o f3.exr",
                                tmp.path());
  INFO(img.err);
  CHECK(img.exit_code == 0);
  CHECK(std::filesystem::exists(tmp.path() / "f3.png"));
  // A lit sequence is replaced by a plain one, as any simulation is.
  CHECK(run_cli("simulate gas.json -o lit -q --frames 1", tmp.path()).exit_code == 0);
  CHECK_FALSE(std::filesystem::exists(tmp.path() / "lit" / "manifest.json"));
  CHECK(run_cli("simulate gas.json -o x --cold -q", tmp.path()).exit_code == 2);
}
