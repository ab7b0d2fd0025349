// lblight validate: load and check a scene without solving, and print what a bake would do.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <cmath>
#include <iostream>
#include <map>
#include <sstream>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "apps/lblight/solve_options.h"
#include "lblight/core/error.h"
#include "lblight/core/system_info.h"
#include "lblight/pipeline/bake_output.h"
#include "lblight/solve/plan_cost.h"
#include "lblight/solve/throughput.h"

namespace lblight::cli {
namespace {

struct ValidateArgs {
  SolveOptions solve;
  bool json = false;
  bool no_timing = false;
};

std::string channel_line(const Material& m) {
  std::ostringstream s;
  s.precision(4);
  for (int c = 0; c < kChannels; ++c) {
    const OpticalParams& p = m.channel[c];
    s << (c ? " | " : "") << kChannelNames[c] << " sigma_a " << p.sigma_a << " sigma_s " << p.sigma_s << " g " << p.g;
  }
  return s.str();
}

// What the plan leaves out, one line each (nothing when it bakes everything).
std::string savings_lines(const ModelPlan& mp) {
  const PlanSavings& sv = mp.savings;
  std::ostringstream t;
  if (!sv.solutions_left_out.empty()) {
    t << "  left out: " << sv.solutions_left_out.size() << " solution(s)";
    for (int idx : sv.solutions_left_out) t << " " << base_grid_name(idx);
    t << " (no sun the scene allows selects them)\n";
  }
  if (!mp.steps.method_note.empty()) t << "  " << mp.steps.method_note << "\n";
  if (sv.ambient_from_sum) t << "  B00 from the sum of B01..B18 (empty boundary layer, docs/model.md sec. 4): not solved\n";
  if (sv.channels_solved < kChannels)
    t << "  " << sv.channels_solved << " channel(s) solved for R, G, B (channels with equal materials share one)\n";
  if (sv.cropped) {
    const Dims& f = sv.full_lattice;
    const Dims& d = mp.lattice.dims;
    t << "  lattice cropped to the occupied nodes plus margin: " << f.nx << "x" << f.ny << "x" << f.nz << " -> " << d.nx
      << "x" << d.ny << "x" << d.nz << " (" << static_cast<int>(std::lround(100.0 * d.count() / f.count()))
      << "% of the nodes)\n";
  }
  const double work = savings_json(mp)["work_fraction"].get<double>();
  if (work < 0.9995) {
    t.precision(3);
    t << "  work: " << 100.0 * work << "% of 19 solutions x 3 channels on the full lattice\n";
  }
  return t.str();
}

int run_validate(const ValidateArgs& args) {
  const Scene scene = load_scene(args.solve.scene);
  const PlanOverrides ov = args.solve.overrides();
  auto backend = args.solve.make_backend("bake");
  const BakePlan plan = make_plan(scene, ov, args.solve.run_context());
  const Precision precision = plan.precision;
  if (!backend->supports(precision))
    throw_invalid(std::string("the ") + backend->name() + " backend cannot store " + to_string(precision),
                  {scene.file.string(), "/solver/precision", {}});
  const double ups = args.no_timing ? 0.0 : measure_updates_per_second(*backend, precision);

  nlohmann::json out;
  out["scene"] = {{"file", scene.file.string()}, {"name", scene.name}, {"hash", scene.hash}};
  out["backend"] = {{"name", backend->name()}, {"description", backend->description()},
                    {"precision", to_string(precision)}, {"updates_per_second", ups}};
  out["models"] = nlohmann::json::array();
  double total_seconds = 0;
  std::ostringstream text;
  text << "scene '" << scene.name << "' (" << scene.file.string() << "), " << scene.hash << "\n";
  text << "backend: " << backend->description() << ", " << to_string(precision) << "\n";
  for (const ModelPlan& mp : plan.models) {
    const Dims& gd = mp.grid.dims;
    const Dims& ld = mp.lattice.dims;
    const PlanCost cost = plan_cost(mp, *backend);
    const double memory = static_cast<double>(cost.device_bytes);
    const double seconds = cost.seconds(ups, host_cores());
    total_seconds += seconds;

    std::string sols;
    for (const SolutionPlan& s : mp.solutions) sols += (sols.empty() ? "" : " ") + s.grid_name;
    text << "model '" << mp.spec->name << "': " << mp.grid.description << "\n";
    // A gas source's grid (and so its lattice) is the smoke of one frame: there is no plan without it.
    if (mp.spec->density.type == SourceType::Gas)
      text << "  (validate ran the gas simulation up to this frame to plan it; `lblight simulate` writes every frame, "
              "with --light lit)\n";
    text << "  density grid " << gd.nx << "x" << gd.ny << "x" << gd.nz << ", voxel size " << mp.grid.voxel_size()[0]
         << "; lattice " << ld.nx << "x" << ld.ny << "x" << ld.nz << " (margin " << mp.spec->margin << "), "
         << mp.stats.occupied << " occupied nodes, " << mp.stats.wood << " wood\n";
    text << "  material '" << mp.spec->material.name << "'" << (mp.spec->material.absorbs ? " (absorbs f0)" : "")
         << ": " << channel_line(mp.spec->material) << "\n";
    if (mp.lattice.has_material(kMaterialWood))
      text << "  wood '" << mp.spec->wood_material.name << "'" << (mp.spec->wood_material.absorbs ? " (absorbs f0)" : "")
           << ": " << channel_line(mp.spec->wood_material) << "\n";
    if (mp.ground.on)
      text << "  ground: albedo " << mp.ground.albedo[0] << ", " << mp.ground.albedo[1] << ", " << mp.ground.albedo[2]
           << ", the lattice's lowest interior layer" << (mp.ground.gap > 0 ? ", " + std::to_string(mp.ground.gap) + " empty layer(s) below the medium" : " (directly below the medium)") << "\n";
    text << "  solutions (" << mp.solutions.size() << "): " << sols << "; " << mp.channels.size()
         << " distinct channel(s) each\n";
    text << savings_lines(mp);
    text << "  LB model: " << mp.model.name() << " (docs/model.md" << (mp.model.calibrated ? " sec. 8" : "") << ")\n";
    text << "  steps: " << to_string(mp.steps.mode);
    if (mp.steps.mode == IterationMode::Auto)
      text << ", tolerance " << mp.steps.tolerance << ", check every " << mp.steps.check_interval << ", min "
           << mp.steps.min_steps << ", max " << mp.steps.max_steps << "; estimated ~"
           << static_cast<long long>(mp.estimated_steps) << " per solution";
    else
      text << ", " << mp.steps.fixed_steps << " per solution";
    text << "\n  memory: " << format_bytes(memory) << " on the " << backend->name() << " backend ("
         << cost.batch_systems << " system(s) of " << format_bytes(static_cast<double>(cost.bytes_per_system))
         << " per batch, state " << to_string(cost.layout) << "), " << format_bytes(cost.host_result_bytes)
         << " of results on the host\n";
    // The scene may be meant for a bigger machine, so here it is a warning.
    if (!cost.fits) spdlog::warn("{}; bake would fail on this machine", cost.why_not);
    if (ups > 0)
      text << "  estimated run time: " << format_seconds(seconds) << " s (" << mp.systems() << " systems x ~"
           << static_cast<long long>(mp.estimated_steps) << " steps at " << format_seconds(ups / 1e6)
           << " M updates/s)\n";

    nlohmann::json m;
    m["name"] = mp.spec->name;
    m["source"] = mp.grid.description;
    m["lattice"] = lattice_json(mp);
    m["occupied_nodes"] = mp.stats.occupied;
    m["wood_nodes"] = mp.stats.wood;
    m["materials"] = {{"medium", material_json(mp.spec->material)}};
    if (mp.lattice.has_material(kMaterialWood)) m["materials"]["wood"] = material_json(mp.spec->wood_material);
    if (mp.ground.on) m["ground"] = {{"albedo", mp.ground.albedo}, {"empty_layers_above", mp.ground.gap}};
    m["solutions"] = nlohmann::json::array();
    for (const SolutionPlan& s : mp.solutions) m["solutions"].push_back(s.grid_name);
    m["distinct_channels"] = mp.channels.size();
    m["savings"] = savings_json(mp);
    m["steps"] = {{"mode", to_string(mp.steps.mode)}, {"estimated_per_solution", mp.estimated_steps}};
    m["memory_bytes"] = memory;
    m["fits_available_memory"] = cost.fits;
    m["estimated_seconds"] = seconds;
    out["models"].push_back(m);
  }
  if (plan.forest) {
    const std::vector<ForestInstance>& all = plan.forest->instances;
    std::map<std::string, int> per_model;
    for (const ForestInstance& i : all) ++per_model[i.model];
    text << "forest: " << all.size() << " instance(s) (" << scene.forest.instances.size() << " listed, "
         << all.size() - scene.forest.instances.size() << " generated):";
    nlohmann::json f = {{"instances", all.size()}, {"listed", scene.forest.instances.size()}};
    for (const auto& [name, n] : per_model) {
      text << " " << name << " x " << n;
      f["per_model"][name] = n;
    }
    if (plan.forest->coarse) {
      text << "\n  coarse forest grid: cells of " << plan.forest->cell_size << " world units ("
           << plan.forest->cell_size_note << "), solved as model 'forest' and each model alone as 'forest.alone.<model>'";
      f["cell_size"] = plan.forest->cell_size;
    } else {
      text << "\n  no coarse forest grid (forest.coarse false): relighting uses each instance's own light only";
    }
    f["coarse"] = plan.forest->coarse;
    text << "\n";
    out["forest"] = f;
  }
  out["warnings"] = plan.warnings;
  out["estimated_seconds"] = total_seconds;
  if (ups > 0) text << "total estimated run time: " << format_seconds(total_seconds) << " s\n";
  for (const std::string& w : plan.warnings) text << "warning: " << w << "\n";
  text << "scene is valid\n";
  std::cout << (args.json ? out.dump(2) + "\n" : text.str());
  return 0;
}

}  // namespace

Command add_validate_command(CLI::App& app, const GlobalOptions&) {
  auto args = std::make_shared<ValidateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "validate",
      "Check a scene without solving (loads and checks every density grid and material) and print the plan: "
      "models, lattice sizes, solutions, memory needed and estimated run time. Exit code 2 names the first "
      "problem.");
  args->solve.add_to(*cmd);
  cmd->add_flag("--json", args->json, "Print the plan as JSON");
  cmd->add_flag("--no-timing", args->no_timing, "Skip the short throughput measurement behind the time estimate");
  return {cmd, [args] { return run_validate(*args); }};
}

}  // namespace lblight::cli
