// lblight relight: one baked model's light for a sun, from its base solutions, as a .vdb that
// Blender and Houdini render as it is (docs/output-format.md, "Relit light").
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <iostream>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/core/error.h"
#include "lblight/core/version.h"
#include "lblight/io/output_dir.h"
#include "lblight/io/vdb_io.h"
#include "lblight/pipeline/relight.h"

namespace fs = std::filesystem;

namespace lblight::cli {
namespace {

struct RelightArgs {
  std::string input, model, output;
  double elevation = 45.0, azimuth = 0.0, intensity = 1.0, ambient = 0.0;
};

int run_relight(const RelightArgs& a, const GlobalOptions& global) {
  fs::path vdb = a.input;
  if (fs::is_directory(vdb)) {
    if (a.model.empty()) {
      std::vector<std::string> names;
      for (const auto& e : fs::directory_iterator(vdb))
        if (e.path().extension() == ".vdb") names.push_back(e.path().stem().string());
      if (names.size() != 1)
        throw_invalid("bake '" + a.input + "' holds " + std::to_string(names.size()) +
                      " model .vdb files; choose one with --model");
      vdb /= names[0] + ".vdb";
    } else {
      vdb /= a.model + ".vdb";
    }
  }
  if (!fs::exists(vdb)) throw_invalid("no such bake file: " + vdb.string());
  RelightRequest req;
  req.toward_sun = toward_sun_from_angles(a.elevation, a.azimuth);
  req.intensity = a.intensity;
  req.ambient = a.ambient;
  RunContext ctx;
  ctx.cancel = &g_interrupted;
  const RelitModel r = relight_model(vdb, req, ctx);
  const fs::path out = a.output.empty() ? fs::path(vdb.stem().string() + "-light.vdb") : fs::path(a.output);
  nlohmann::json weights = nlohmann::json::array();
  for (const auto& [solution, weight] : r.weights) weights.push_back({solution, weight});
  const nlohmann::json box = {{"lblight_lattice_min", r.frame.index_min},
                              {"lblight_lattice_dims", {r.frame.dims.nx, r.frame.dims.ny, r.frame.dims.nz}}};
  nlohmann::json lmeta = box;
  lmeta["lblight_meaning"] = "light of a static bake of this sun: intensity x (the sun's three base solutions by "
                             "their weights) + ambient x B00; 1 = the open-air value of a unit sun";
  nlohmann::json dmeta = box;
  const nlohmann::json meta = {{"lblight_version", kVersion},
                               {"lblight_command", global.command_line},
                               {"lblight_source", vdb.string()},
                               {"lblight_sun_elevation", a.elevation},
                               {"lblight_sun_azimuth", a.azimuth},
                               {"lblight_intensity", a.intensity},
                               {"lblight_ambient", a.ambient},
                               {"lblight_weights", weights.dump()}};
  const std::vector<DenseGridOut> grids = {{"light", nullptr, &r.light, false, lmeta},
                                           {"density", &r.density, nullptr, true, dmeta}};
  // Written under a temporary name and renamed: the output appears complete or not at all.
  write_file_atomically(out, [&](const fs::path& tmp) {
    write_vdb(tmp, r.frame, grids, meta);
    throw_if_interrupted();
  });
  std::cout << "relit " << vdb.string() << " for a sun at elevation " << a.elevation << ", azimuth " << a.azimuth
            << " (weights " << weights.dump() << "): " << out.string() << "\n";
  return 0;
}

}  // namespace

Command add_relight_command(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<RelightArgs>();
  CLI::App* cmd = app.add_subcommand(
      "relight",
      "One baked model's light for a sun, assembled from its base solutions (intensity x the three lattice "
      "directions around the sun, weighted as [Steele2009] sec. 4.2, + ambient x B00): the same light a static bake "
      "of that sun gives. Writes a .vdb with a vec3 'light' grid (active on the occupied nodes and their neighbours) "
      "and the 'density' grid. Names the base solution a sun needs when the bake left it out.");
  cmd->add_option("bake", args->input, "Bake output folder (or one model's .vdb)")->required();
  cmd->add_option("--model", args->model, "Model to relight (needed when the bake holds several)")->check(kNonEmpty);
  cmd->add_option("--sun-elevation", args->elevation, "Degrees above the horizon (90 = zenith)")
      ->check(finite_range(-90.0, 90.0))
      ->capture_default_str();
  cmd->add_option("--sun-azimuth", args->azimuth, "Degrees from +x toward +y")
      ->check(finite_range(-360.0, 360.0))
      ->capture_default_str();
  cmd->add_option("--intensity", args->intensity, "Sun intensity s")->check(finite_range(0.0, 1e6))->capture_default_str();
  cmd->add_option("--ambient", args->ambient, "Ambient level a (x B00)")->check(finite_range(0.0, 1e6))->capture_default_str();
  cmd->add_option("-o,--output", args->output, "Output .vdb (default: <model>-light.vdb here)")->check(kNonEmpty);
  return {cmd, [args, &global] { return run_relight(*args, global); }};
}

}  // namespace lblight::cli
