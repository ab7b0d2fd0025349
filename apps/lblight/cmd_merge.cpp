// lblight merge: the partial outputs of a bake's work units (bake --only) into the output a
// one-machine bake writes (docs/scale-out.md).
#include <CLI/CLI.hpp>

#include <filesystem>
#include <iostream>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/io/output_dir.h"
#include "lblight/pipeline/work_units.h"
#include "lblight/solve/plan.h"

namespace fs = std::filesystem;

namespace lblight::cli {
namespace {

struct MergeArgs {
  std::vector<std::string> parts;
  std::string output, scene;
};

int run_merge(const MergeArgs& a, const GlobalOptions& global) {
  MergeOptions options;
  options.command_line = global.command_line;
  if (!a.scene.empty()) {  // every part must be of this scene, and every one of its units there
    const Scene scene = load_scene(a.scene);
    options.scene_hash = scene.hash;
    options.scene_name = scene.name;
    options.scene_file = scene.file.string();
    options.units = lattice_names(scene);
  }
  RunContext ctx;
  ctx.cancel = &g_interrupted;
  const fs::path target = output_folder_path(a.output);
  std::vector<fs::path> parts(a.parts.begin(), a.parts.end());
  const nlohmann::json m = merge_parts(parts, target, options, ctx);
  std::cout << "merged " << parts.size() << " part(s), " << m["models"].size() << " unit(s) of scene '"
            << m["scene"].value("name", "")
            << "' into " << target.string() << "\n";
  return 0;
}

}  // namespace

Command add_merge_command(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<MergeArgs>();
  CLI::App* cmd = app.add_subcommand(
      "merge",
      "Combine the partial outputs of a bake's work units (lblight bake --only UNIT, one folder each) into OUTDIR: "
      "exactly what one `lblight bake` writes (the same files; the manifest equal except its run record: created, "
      "command, timings). A part that is damaged (a file changed or cut short), of another scene or lblight "
      "version, or a unit missing or given twice stops the merge (exit 2) naming the part; OUTDIR then stays "
      "untouched. A unit baked in shares of its solutions is assembled from their totals through the bake's own "
      "output (B00 summed as a bake sums it); that needs the scene (--scene, else the path the parts record).");
  cmd->add_option("parts", args->parts,
                  "Partial output folders: one per unit, or for a unit baked in shares (--only MODEL:SOLUTIONS) "
                  "one per share")
      ->required()
      ->check(kNonEmpty);
  cmd->add_option("-o,--output", args->output, "Output directory; replaced if it holds a previous lblight output")
      ->required()
      ->check(kNonEmpty);
  cmd->add_option("--scene", args->scene,
                  "The scene the parts were baked from: every part must be of it (else refused as foreign), and "
                  "every one of its units given (default: the first part's scene)")
      ->check(kNonEmpty);
  return {cmd, [args, &global] { return run_merge(*args, global); }};
}

}  // namespace lblight::cli
