// lblight relight: a baked model's light for a sun from its base solutions equals a static bake of
// that sun (float precision), and a sun the bake cannot serve is refused by name.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "lblight/io/vdb_io.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {

std::string plant_scene(const std::string& lighting) {
  return R"({"version": 1, "models": [{"name": "tree", "density": {"type": "procedural", "shape": "plant",
             "resolution": 12, "seed": 4}, "material": "leaf", "wood_material": "paper-bark"}],
             "lighting": )" + lighting + R"(, "solver": {"iterations": "auto", "tolerance": 1e-6, "model": "paper"}})";
}

}  // namespace

TEST_CASE("relight of the base solutions equals the static bake of that sun, on the medium", "[cli]") {
  TempDir tmp;
  write_text(tmp / "base.json", plant_scene(R"({"mode": "base", "solutions": "all"})"));
  write_text(tmp / "static.json",
             plant_scene(R"({"mode": "static", "sun": {"elevation": 35, "azimuth": 120}, "intensity": 1.7, "ambient": 0.3})"));
  REQUIRE(run_cli("bake base.json -o base --backend cpu -q", tmp.path()).exit_code == 0);
  REQUIRE(run_cli("bake static.json -o static --backend cpu -q", tmp.path()).exit_code == 0);
  const CliResult r = run_cli(
      "relight base --sun-elevation 35 --sun-azimuth 120 --intensity 1.7 --ambient 0.3 -o relit.vdb", tmp.path());
  INFO(r.out << r.err);
  REQUIRE(r.exit_code == 0);
  const DenseGridIn relit = read_vdb_grid_dense(tmp / "relit.vdb", "light");
  const DenseGridIn stat = read_vdb_grid_dense(tmp / "static" / "tree.vdb", "light");
  const DenseGridIn density = read_vdb_grid_dense(tmp / "relit.vdb", "density");
  REQUIRE(relit.frame.dims == stat.frame.dims);
  // Self-describing: the bake's and the relit file's density carry the materials and voxel size,
  // and the relit file keeps where the wood is.
  for (const std::filesystem::path file : {tmp / "base" / "tree.vdb", tmp / "relit.vdb"}) {
    const nlohmann::json& meta = read_vdb_grid_dense(file, "density").metadata;
    INFO(file << ": " << meta.dump());
    REQUIRE(meta.contains("lblight_material_medium"));
    const nlohmann::json medium = nlohmann::json::parse(meta["lblight_material_medium"].get<std::string>());
    CHECK(medium["sigma_s"][1].get<double>() == Approx(0.909));  // the leaf preset
    const nlohmann::json wood = nlohmann::json::parse(meta["lblight_material_wood"].get<std::string>());
    CHECK(wood["g"][0].get<double>() == -1.0);  // paper-bark
    CHECK(meta["lblight_voxel_size"].get<double>() > 0);
    CHECK(meta["lblight_lb_model"] == "paper");
  }
  const DenseGridIn brown = read_vdb_grid_dense(tmp / "relit.vdb", "brown");
  CHECK(std::count(brown.values[0].begin(), brown.values[0].end(), 1.0f) > 0);
  const Dims& d = relit.frame.dims;
  double worst = 0, peak = 0;
  int compared = 0, boundary_values = 0;
  for (int z = 0; z < d.nz; ++z)
    for (int y = 0; y < d.ny; ++y)
      for (int x = 0; x < d.nx; ++x) {
        const std::size_t i = d.index(x, y, z);
        for (int c = 0; c < 3; ++c) {
          if (d.is_boundary(x, y, z)) {
            boundary_values += relit.values[c][i] != 0.0f;  // source values never appear
            continue;
          }
          if (density.values[0][i] <= 0.0f) continue;
          worst = std::max(worst, std::fabs(static_cast<double>(relit.values[c][i]) - stat.values[c][i]));
          peak = std::max(peak, static_cast<double>(stat.values[c][i]));
          ++compared;
        }
      }
  CHECK(compared > 100);
  CHECK(boundary_values == 0);
  CHECK(worst <= 2e-5 * peak);  // two runs to 1e-6 each, stored in float32
}

TEST_CASE("relighting the base solutions' flux gives the flux of the static bake of that sun", "[cli][moments]") {
  // docs/model.md sec. 3.2: the flux is linear in the boundary as the light is. With the calibrated
  // model and first_collision, B00 is solved from a source and its flux is the directional
  // solutions' sum (solve/bake.h, BakeOptions::moments): the ambient part checks that path.
  // (base bake's solver, static bake's solver): a static bake has no B00 to correct.
  for (const auto& [base_solver, static_solver] :
       {std::pair<std::string, std::string>{R"("model": "paper")", R"("model": "paper")"},
        std::pair<std::string, std::string>{R"("calibration": {"first_collision": true})", R"("model": "calibrated")"}}) {
    TempDir tmp;
    const auto scene = [&](const std::string& lighting, const std::string& solver) {
      return R"({"version": 1, "models": [{"name": "tree", "density": {"type": "procedural", "shape": "plant",
             "resolution": 12, "seed": 4}, "material": "leaf"}], "lighting": )" +
             lighting + R"(, "solver": {"iterations": "auto", "tolerance": 1e-6, )" + solver + "}}";
    };
    const std::string& solver = base_solver;
    write_text(tmp / "base.json", scene(R"({"mode": "base", "solutions": "all"})", base_solver));
    write_text(tmp / "static.json",
               scene(R"({"mode": "static", "sun": {"elevation": 35, "azimuth": 120}, "intensity": 1.7, "ambient": 0.3})",
                     static_solver));
    REQUIRE(run_cli("bake base.json -o base --backend cpu -q", tmp.path()).exit_code == 0);
    REQUIRE(run_cli("bake static.json -o static --backend cpu -q", tmp.path()).exit_code == 0);
    const CliResult r = run_cli(
        "relight base --sun-elevation 35 --sun-azimuth 120 --intensity 1.7 --ambient 0.3 -o relit.vdb", tmp.path());
    INFO(solver << "\n" << r.out << r.err);
    REQUIRE(r.exit_code == 0);
    const DenseGridIn density = read_vdb_grid_dense(tmp / "relit.vdb", "density");
    const DenseGridIn light = read_vdb_grid_dense(tmp / "static" / "tree.vdb", "light");
    for (const char* channel : {"r", "g", "b"}) {
      const DenseGridIn relit = read_vdb_grid_dense(tmp / "relit.vdb", std::string("light_flux_") + channel);
      const DenseGridIn stat = read_vdb_grid_dense(tmp / "static" / "tree.vdb", std::string("light_flux_") + channel);
      REQUIRE(relit.frame.dims == stat.frame.dims);
      double worst = 0, peak = 0, largest_flux = 0;
      for (std::size_t i = 0; i < density.values[0].size(); ++i) {
        if (density.values[0][i] <= 0.0f) continue;
        peak = std::max(peak, static_cast<double>(light.values[0][i]));
        for (int a = 0; a < 3; ++a) {
          worst = std::max(worst, std::fabs(static_cast<double>(relit.values[a][i]) - stat.values[a][i]));
          largest_flux = std::max(largest_flux, std::fabs(static_cast<double>(stat.values[a][i])));
        }
      }
      INFO(channel << ": worst " << worst << ", peak light " << peak << ", largest flux " << largest_flux);
      CHECK(largest_flux > 0.1 * peak);  // a sun's light flows: the flux is not small
      CHECK(worst <= 2e-5 * peak);
    }
  }
}

TEST_CASE("relight names the base solution a sun needs when the bake left it out", "[cli]") {
  TempDir tmp;
  write_text(tmp / "sky.json", plant_scene(R"({"mode": "base", "solutions": "auto",
             "sun_range": {"min_elevation": 30, "max_elevation": 90}})"));
  REQUIRE(run_cli("bake sky.json -o sky --backend cpu -q --tolerance 1e-3", tmp.path()).exit_code == 0);
  CHECK(run_cli("relight sky --sun-elevation 60 -o ok.vdb", tmp.path()).exit_code == 0);
  const CliResult r = run_cli("relight sky --sun-elevation -40 -o below.vdb", tmp.path());
  CHECK(r.exit_code == 2);
  CHECK(r.err.find("left out") != std::string::npos);
  CHECK(!std::filesystem::exists(tmp.path() / "below.vdb"));
}

TEST_CASE("relight --sky lights from the upper hemisphere only: the plant's base is no longer its brightest part", "[cli]") {
  TempDir tmp;
  write_text(tmp / "base.json", plant_scene(R"({"mode": "base", "solutions": "all"})"));
  REQUIRE(run_cli("bake base.json -o base --backend cpu -q --tolerance 1e-4", tmp.path()).exit_code == 0);
  REQUIRE(run_cli("relight base --intensity 0 --sky 1 -o sky.vdb", tmp.path()).exit_code == 0);
  REQUIRE(run_cli("relight base --intensity 0 --ambient 1 -o ambient.vdb", tmp.path()).exit_code == 0);
  const DenseGridIn sky = read_vdb_grid_dense(tmp / "sky.vdb", "light");
  const DenseGridIn ambient = read_vdb_grid_dense(tmp / "ambient.vdb", "light");
  const DenseGridIn density = read_vdb_grid_dense(tmp / "sky.vdb", "density");
  const Dims& d = sky.frame.dims;
  // Mean light of the occupied nodes in the lowest and the highest occupied layer.
  auto layer_mean = [&](const DenseGridIn& g, bool top) {
    for (int k = 0; k < d.nz; ++k) {
      const int z = top ? d.nz - 1 - k : k;
      double sum = 0;
      int n = 0;
      for (int y = 0; y < d.ny; ++y)
        for (int x = 0; x < d.nx; ++x)
          if (density.values[0][d.index(x, y, z)] > 0.0f) {
            sum += g.values[1][d.index(x, y, z)];
            ++n;
          }
      if (n > 0) return sum / n;
    }
    return 0.0;
  };
  const double sky_base = layer_mean(sky, false), sky_top = layer_mean(sky, true);
  const double amb_base = layer_mean(ambient, false), amb_top = layer_mean(ambient, true);
  INFO("sky: base " << sky_base << ", crown top " << sky_top << "; ambient: base " << amb_base << ", top " << amb_top);
  // Ambient light from below makes the trunk's base brighter than the crown (what users saw);
  // the sky turns that round.
  CHECK(amb_base > amb_top);
  CHECK(sky_base < sky_top);
  CHECK(sky_base / sky_top < 0.85 * amb_base / amb_top);
  // Everywhere: the sky is part of the ambient of the same radiance, about half of it in the open.
  for (std::size_t i = 0; i < density.values[0].size(); ++i)
    if (density.values[0][i] > 0.0f) REQUIRE(sky.values[1][i] < ambient.values[1][i]);
}

TEST_CASE("sun-weights prints the grids and weights a sun selects, and the 32 faces", "[cli]") {
  const CliResult zenith = run_cli("sun-weights --elevation 90 --json");
  REQUIRE(zenith.exit_code == 0);
  const auto z = nlohmann::json::parse(zenith.out);
  REQUIRE(z["weights"].size() >= 1);
  double b06 = 0, total = 0;
  for (const auto& w : z["weights"]) {
    total += w["weight"].get<double>();
    if (w["grid"] == "B06") b06 = w["weight"].get<double>();
  }
  CHECK(b06 == Approx(1.0));  // straight down: direction (0, 0, -1)
  CHECK(total == Approx(1.0));
  const CliResult s = run_cli("sun-weights --elevation 35 --azimuth 120 --intensity 1.5 --ambient 0.1 --json");
  REQUIRE(s.exit_code == 0);
  const auto j = nlohmann::json::parse(s.out);
  double sun = 0, ambient = 0;
  for (const auto& w : j["weights"]) (w["grid"] == "B00" ? ambient : sun) += w["weight"].get<double>();
  CHECK(sun == Approx(1.5));
  CHECK(ambient == Approx(0.1));
  const CliResult f = run_cli("sun-weights --faces --json");
  REQUIRE(f.exit_code == 0);
  CHECK(nlohmann::json::parse(f.out).size() == 32);
}
