// lblight compare: two bakes of the same scene, grid by grid (GPU against CPU, float16 against
// float32, a new build against a stored regression result).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>

#include <nlohmann/json.hpp>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/core/error.h"
#include "lblight/core/relative_gap.h"
#include "lblight/io/vdb_io.h"

namespace fs = std::filesystem;

namespace lblight::cli {
namespace {

struct CompareArgs {
  std::string reference, other;
  double tolerance = 1e-5;
};

nlohmann::json read_manifest(const fs::path& dir) {
  const fs::path file = dir / "manifest.json";
  std::ifstream in(file);
  if (!in) throw_invalid("not an lblight output directory (no manifest.json)", {dir.string(), {}, {}});
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw_invalid(std::string("cannot parse: ") + e.what(), {file.string(), {}, {}});
  }
}

// Per grid, each value's difference relative to the reference value; values below 1e-6 of the
// grid's largest are measured against that floor: light that faint is rounding noise in either bake.
double grid_difference(const DenseGridIn& ref, const DenseGridIn& got) {
  double largest = 0.0;
  for (const auto& ch : ref.values) largest = std::max(largest, peak_magnitude(ch));
  const double floor = std::max(1e-30, 1e-6 * largest);
  double worst = 0.0;
  for (std::size_t c = 0; c < ref.values.size(); ++c)
    keep_worst(worst, max_relative_difference(ref.values[c], got.values[c], floor));
  return worst;
}

int compare_outputs(const CompareArgs& a) {
  const fs::path ref_dir = a.reference, other_dir = a.other;
  const nlohmann::json ref = read_manifest(ref_dir), other = read_manifest(other_dir);
  double worst = 0.0;
  int grids = 0;
  for (const auto& model : ref.at("models")) {
    const std::string name = model.at("name");
    const auto it = std::find_if(other.at("models").begin(), other.at("models").end(),
                                 [&](const nlohmann::json& m) { return m.at("name") == name; });
    if (it == other.at("models").end())
      throw_invalid("model '" + name + "' is not in this output", {other_dir.string(), {}, {}});
    if (it->at("lattice").at("dims") != model.at("lattice").at("dims") ||
        it->at("lattice").at("index_min") != model.at("lattice").at("index_min"))
      throw_invalid("model '" + name + "' is on another lattice than in " + ref_dir.string(),
                    {other_dir.string(), {}, {}});
    for (const auto& [m, dir] : {std::pair{&model, &ref_dir}, std::pair{&*it, &other_dir}})
      if (m->at("file").is_null())
        throw_invalid("model '" + name + "' has no .vdb in this output (baked with \"output\": {\"vdb\": false}); "
                      "compare reads the .vdb grids",
                      {dir->string(), {}, {}});
    const fs::path fa = ref_dir / model.at("file").get<std::string>();
    const fs::path fb = other_dir / it->at("file").get<std::string>();
    for (const auto& s : model.at("solutions")) {
      const std::string grid = s.at("grid");
      const double d = grid_difference(read_vdb_grid_dense(fa, grid), read_vdb_grid_dense(fb, grid));
      std::printf("%s %s: max relative difference %.3g\n", name.c_str(), grid.c_str(), d);
      keep_worst(worst, d);
      ++grids;
    }
  }
  const bool ok = worst <= a.tolerance;
  std::printf("largest over %d grid(s): %.3g (%s %g)\n", grids, worst, ok ? "within" : "ABOVE", a.tolerance);
  return ok ? 0 : 1;
}

int run_compare(const CompareArgs& a) {
  try {
    return compare_outputs(a);
  } catch (const nlohmann::json::exception& e) {  // a manifest without the fields a bake writes
    throw_invalid(std::string("manifest.json is not an lblight bake manifest: ") + e.what(),
                  {a.reference + " or " + a.other, {}, {}});
  }
}

}  // namespace

Command add_compare_command(CLI::App& app, const GlobalOptions&) {
  auto args = std::make_shared<CompareArgs>();
  CLI::App* cmd = app.add_subcommand(
      "compare",
      "Compare the light grids of two bakes of the same scene (every model and solution of the reference): per grid "
      "the largest relative difference, with values below 1e-6 of the grid's largest compared against that floor. "
      "Exit 0 when every grid is within --tolerance, 1 when one is not, 2 when the outputs do not match up.");
  cmd->add_option("reference", args->reference, "Reference output directory (with manifest.json)")->required();
  cmd->add_option("other", args->other, "Output directory to compare against it")->required();
  cmd->add_option("--tolerance", args->tolerance, "Largest relative difference allowed (default 1e-5)")
      ->check(finite_range(0.0, 1e30));
  return {cmd, [args] { return run_compare(*args); }};
}

}  // namespace lblight::cli
