// lblight relight: one baked model's light for a sun, from its base solutions, as a .vdb that
// Blender and Houdini render as it is (docs/output-format.md, "Relit light").
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>
#include <iostream>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/core/error.h"
#include "lblight/core/version.h"
#include "lblight/io/output_dir.h"
#include "lblight/io/run_paths.h"
#include "lblight/io/vdb_io.h"
#include "lblight/pipeline/manifest.h"
#include "lblight/pipeline/relight.h"
#include "lblight/pipeline/relight_forest.h"
#include "lblight/scene/material.h"

namespace fs = std::filesystem;

namespace lblight::cli {
namespace {

struct RelightArgs {
  std::string input, model, output;
  double elevation = 45.0, azimuth = 0.0, intensity = 1.0, ambient = 0.0, sky = 0.0;
  bool local = false;
  double voxel_size = 0;
  long long instance = -1;
  int threads = 0;
};

bool holds_forest(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec) || !fs::exists(dir / "manifest.json", ec)) return false;
  return read_manifest(dir).contains("forest");
}

// The whole forest (or one instance of it) into one world-space volume, and a JSON record of the
// weights and coarse factors each instance used next to it.
int run_relight_forest(const RelightArgs& a, const GlobalOptions& global) {
  ForestRelightRequest req;
  req.sun.toward_sun = toward_sun_from_angles(a.elevation, a.azimuth);
  req.sun.intensity = a.intensity;
  req.sun.ambient = a.ambient;
  req.sun.sky = a.sky;
  req.coarse = !a.local;
  req.voxel_size = a.voxel_size;
  if (a.instance >= 0) req.instance = static_cast<std::size_t>(a.instance);
  RunContext ctx;
  ctx.cancel = &g_interrupted;
  ctx.threads = usable_threads(a.threads);
  const fs::path out = a.output.empty() ? fs::path("forest-light.vdb") : fs::path(a.output);
  fs::path rec_file = out;
  rec_file.replace_extension(".json");
  RunPaths().input(a.input, "the bake").output_file(out, "-o").output_file(rec_file, "the weights record").check();
  const nlohmann::json meta = {{"lblight_version", kVersion},
                               {"lblight_command", global.command_line},
                               {"lblight_source", a.input},
                               {"lblight_sun_elevation", a.elevation},
                               {"lblight_sun_azimuth", a.azimuth},
                               {"lblight_intensity", a.intensity},
                               {"lblight_ambient", a.ambient},
                               {"lblight_sky", a.sky},
                               {"lblight_coarse_factors", req.coarse},
                               {"lblight_delta_m", bake_solved_with_delta_m(a.input)}};
  const ForestRelightResult r = relight_forest(a.input, req, out, meta, ctx);
  nlohmann::json rec = {{"source", a.input},
                        {"output", out.string()},
                        {"sun", {{"elevation", a.elevation}, {"azimuth", a.azimuth}, {"intensity", a.intensity}}},
                        {"ambient", a.ambient},
                        {"sky", a.sky},
                        {"coarse_factors", r.coarse},
                        {"voxel_size", r.voxel_size},
                        {"active_voxels", r.active_voxels},
                        {"seconds", {{"read", r.read_seconds}, {"relight", r.relight_seconds}, {"write", r.write_seconds}}},
                        {"instance_columns", {"instance", "model", "weights [[solution, weight]...] in the model's frame",
                                              "mean coarse factor [r, g, b]", "voxels"}}};
  nlohmann::json fw = nlohmann::json::array();
  for (const auto& [solution, weight] : r.forest_weights) fw.push_back({solution, weight});
  rec["forest_weights"] = fw;
  nlohmann::json rows = nlohmann::json::array();
  for (std::size_t k = 0; k < r.per_instance.size(); ++k) {
    const InstanceRelight& in = r.per_instance[k];
    nlohmann::json w = nlohmann::json::array();
    for (const auto& [solution, weight] : in.weights) w.push_back({solution, weight});
    rows.push_back({req.instance ? *req.instance : k, in.model, w, in.mean_factor, in.voxels});
  }
  rec["instances"] = rows;
  // The volume and its weights record are one output: without the record (a full disk, Ctrl-C)
  // the volume is taken back, so neither is left alone.
  try {
    throw_if_interrupted();
    write_file_atomically(rec_file, rec.dump(1) + "\n");
  } catch (...) {
    std::error_code ec;
    fs::remove(out, ec);
    throw;
  }
  std::cout << "relit " << r.instances << " instance(s) of " << a.input << " for a sun at elevation " << a.elevation
            << ", azimuth " << a.azimuth << (r.coarse ? " with coarse forest factors" : " (local light only)") << ": "
            << r.active_voxels << " active voxels of " << r.voxel_size << " world units in " << r.relight_seconds
            << " s (+ " << r.read_seconds << " s reading, " << r.write_seconds << " s writing): " << out.string()
            << ", weights and factors in " << rec_file.string() << "\n";
  return 0;
}

int run_relight(const RelightArgs& a, const GlobalOptions& global) {
  if (!a.output.empty() && fs::path(a.output).extension() != ".vdb")
    throw_invalid("-o '" + a.output + "' does not end in .vdb; allowed: a .vdb file name (a forest's weights go "
                  "beside it, in the same name with .json)",
                  {a.output, {}, {}});
  if (a.model.empty() && holds_forest(a.input)) return run_relight_forest(a, global);
  if (a.local || a.voxel_size > 0 || a.instance >= 0)
    throw_invalid("--local, --voxel-size and --instance relight a forest; '" + a.input +
                  "' is " + (a.model.empty() ? "not a forest bake" : "relit as one model (--model)"));
  fs::path vdb = a.input;
  if (fs::is_directory(vdb)) {
    if (a.model.empty()) {
      std::vector<std::string> names;
      for (const auto& e : fs::directory_iterator(vdb))
        if (e.path().extension() == ".vdb") names.push_back(e.path().stem().string());
      names.erase(std::remove_if(names.begin(), names.end(),
                                 [](const std::string& n) { return n.rfind("forest", 0) == 0 && (n == "forest" || n.rfind("forest.", 0) == 0); }),
                  names.end());
      if (names.size() != 1)
        throw_invalid("bake '" + a.input + "' holds " + std::to_string(names.size()) +
                      " model .vdb files; choose one with --model");
      vdb /= names[0] + ".vdb";
    } else {
      vdb /= a.model + ".vdb";
    }
  }
  if (!fs::exists(vdb)) throw_invalid("no such bake file: " + vdb.string());
  const fs::path out = a.output.empty() ? fs::path(vdb.stem().string() + "-light.vdb") : fs::path(a.output);
  RunPaths().input(a.input, "the bake").input(vdb, "the bake").output_file(out, "-o").check();
  RelightRequest req;
  req.toward_sun = toward_sun_from_angles(a.elevation, a.azimuth);
  req.intensity = a.intensity;
  req.ambient = a.ambient;
  req.sky = a.sky;
  RunContext ctx;
  ctx.cancel = &g_interrupted;
  const RelitModel r = relight_model(vdb, req, ctx);
  nlohmann::json weights = nlohmann::json::array();
  for (const auto& [solution, weight] : r.weights) weights.push_back({solution, weight});
  const nlohmann::json box = {{"lblight_lattice_min", r.frame.index_min},
                              {"lblight_lattice_dims", {r.frame.dims.nx, r.frame.dims.ny, r.frame.dims.nz}}};
  nlohmann::json lmeta = box;
  lmeta["lblight_meaning"] = "light of a static bake of this sun: intensity x (the sun's three base solutions by "
                             "their weights) + ambient x B00 + sky x (downward directions + half the level ones); 1 = the open-air value "
                             "of a unit sun (ambient a: 18 a, sky S: 9 S)";
  // The bake density's self-description (docs/output-format.md) travels with the relit file, all
  // of it: whatever bake_output.cpp's material_metadata writes, on the same lattice box.
  nlohmann::json dmeta = box;
  for (const auto& [key, value] : r.density_metadata.items())
    if (key.rfind("lblight_", 0) == 0 && !box.contains(key)) dmeta[key] = value;
  const nlohmann::json meta = {{"lblight_version", kVersion},
                               {"lblight_command", global.command_line},
                               {"lblight_source", vdb.string()},
                               {"lblight_sun_elevation", a.elevation},
                               {"lblight_sun_azimuth", a.azimuth},
                               {"lblight_intensity", a.intensity},
                               {"lblight_ambient", a.ambient},
                               {"lblight_sky", a.sky},
                               {"lblight_weights", weights.dump()},
                               {"lblight_delta_m", bake_solved_with_delta_m(vdb)}};
  std::vector<DenseGridOut> grids = {{"light", nullptr, &r.light, false, lmeta},
                                     {"density", &r.density, nullptr, true, dmeta}};
  if (!r.wood.empty()) grids.push_back({"brown", &r.wood, nullptr, false, box});  // where the wood material applies
  if (!r.flux[0][0].empty())  // the relit flux (a bake with moments), for phase-aware rendering
    for (int c = 0; c < 3; ++c) {
      nlohmann::json fmeta = box;
      fmeta["lblight_moment"] = "flux";
      fmeta["lblight_units"] = std::string("flux vector of the light's ") + kChannelNames[c] +
                               " channel along the index axes, relit with the same weights";
      grids.push_back({std::string("light_flux_") + "rgb"[c], nullptr, &r.flux[static_cast<std::size_t>(c)], false, fmeta});
    }
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
      "A bake's light for a sun, assembled from its base solutions (intensity x the three lattice directions "
      "around the sun, weighted as [Steele2009] sec. 4.2, + ambient x B00): the same light a static bake of that sun "
      "gives. One model (--model, or a bake of one model): a .vdb with a vec3 'light' grid (active on the occupied "
      "nodes and their neighbours) and 'density'. A forest bake: every instance (the sun turned into its frame) "
      "scaled by the coarse forest grid's shading ([Steele2009] sec. 4.3; --local: without), resampled into one "
      "world-space volume 'light' + 'density' (+ 'brown'), and the weights and factors used in <output>.json "
      "(docs/forest.md). Names the base solution a sun needs when the bake left it out.");
  cmd->add_option("bake", args->input, "Bake output folder (or one model's .vdb)")->required();
  cmd->add_option("--model", args->model, "Model to relight (needed when the bake holds several)")->check(kNonEmpty);
  cmd->add_option("--sun-elevation", args->elevation, "Degrees above the horizon (90 = zenith)")
      ->check(finite_range(-90.0, 90.0))
      ->capture_default_str();
  cmd->add_option("--sun-azimuth", args->azimuth, "Degrees from +x toward +y")
      ->check(finite_range(-360.0, 360.0))
      ->capture_default_str();
  cmd->add_option("--intensity", args->intensity, "Sun intensity s")->check(finite_range(0.0, 1e6))->capture_default_str();
  cmd->add_option("--ambient", args->ambient, "Ambient level a (x B00): light from every direction, below included")
      ->check(finite_range(0.0, 1e6))
      ->capture_default_str();
  cmd->add_option("--sky", args->sky,
                  "Sky level S: the same radiance from the upper hemisphere only (the downward lattice directions, half "
                  "the level ones); needs those base solutions")
      ->check(finite_range(0.0, 1e6))
      ->capture_default_str();
  cmd->add_option("-o,--output", args->output, "Output .vdb (default: <model>-light.vdb, or forest-light.vdb, here)")
      ->check(kNonEmpty);
  cmd->add_flag("--local", args->local, "Forest: each instance's own light only, without the coarse forest factors");
  cmd->add_option("--voxel-size", args->voxel_size, "Forest: world voxel edge (default: the finest instance voxel)")
      ->check(finite_range(1e-4, 1e6));
  cmd->add_option("--instance", args->instance, "Forest: relight only this instance (0-based, the manifest's order)")
      ->check(CLI::Range(0LL, 100000000LL));
  cmd->add_option("--threads", args->threads, "Forest: CPU threads (0 = all cores); the result does not depend on it")
      ->check(CLI::Range(0, 4096));
  return {cmd, [args, &global] { return run_relight(*args, global); }};
}

}  // namespace lblight::cli
