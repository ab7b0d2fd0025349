// lblight compare: two bakes of the same scene, grid by grid (GPU against CPU, float16 against
// float32, a new build against a stored regression result).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>

#include <nlohmann/json.hpp>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/core/error.h"
#include "lblight/core/relative_gap.h"
#include "lblight/io/vdb_io.h"
#include "lblight/pipeline/manifest.h"
#include "lblight/pipeline/relight.h"
#include "lblight/solve/plan.h"
#include "lblight/pipeline/work_units.h"

namespace fs = std::filesystem;

namespace lblight::cli {
namespace {

struct CompareArgs {
  std::string reference, other;
  double tolerance = 1e-5;
  std::string metric = "max";
  bool exact = false;
};

// The bake output `dir`'s manifest; a folder without one is not an lblight output.
nlohmann::json output_manifest(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw_invalid("not a folder; allowed: an lblight bake output folder", {dir.string(), {}, {}});
  if (!fs::exists(dir / "manifest.json", ec))
    throw_invalid("not an lblight output directory (no manifest.json)", {dir.string(), {}, {}});
  return read_manifest(dir);
}

// A manifest without models compares equal to anything: refused, not "0 differences".
void refuse_empty(const nlohmann::json& manifest, const fs::path& dir) {
  if (manifest.at("models").empty())
    throw_invalid("the manifest lists no model, so there is nothing to compare; allowed: a bake output with at "
                  "least one model",
                  {(dir / "manifest.json").string(), "/models", {}});
}

// 0..18 for a grid named B00..B18, else -1.
int base_solution_index(const std::string& grid) {
  for (int j = 0; j < 19; ++j)
    if (grid == base_grid_name(j)) return j;
  return -1;
}

// Per grid, each value's difference relative to the reference value; values below 1e-6 of the
// grid's largest are measured against that floor: light that faint is rounding noise in either bake.
// Grids of another type or lattice are not comparable (an input error, not a difference).
void check_comparable(const DenseGridIn& ref, const DenseGridIn& got, const fs::path& ref_file,
                      const fs::path& got_file) {
  if (got.type != ref.type)
    throw_invalid("grid '" + got.name + "' is " + got.type + " here but " + ref.type + " in " + ref_file.string(),
                  {got_file.string(), {}, {}});
  if (!(got.frame.dims == ref.frame.dims) || got.frame.index_min != ref.frame.index_min)
    throw_invalid("grid '" + got.name + "' covers another lattice box than in " + ref_file.string(),
                  {got_file.string(), {}, {}});
  if (got.frame.index_to_world != ref.frame.index_to_world)
    throw_invalid("grid '" + got.name + "' has another transform (voxel size, rotation or position in the world) "
                  "than in " + ref_file.string(),
                  {got_file.string(), {}, {}});
}

double grid_difference(const DenseGridIn& ref, const DenseGridIn& got, const fs::path& ref_file,
                       const fs::path& got_file) {
  check_comparable(ref, got, ref_file, got_file);
  double largest = 0.0;
  for (const auto& ch : ref.values) keep_worst(largest, peak_magnitude(ch));
  const double floor = std::max(1e-30, 1e-6 * largest);
  double worst = 0.0;
  for (std::size_t c = 0; c < ref.values.size(); ++c)
    keep_worst(worst, max_relative_difference(ref.values[c], got.values[c], floor));
  return worst;
}

// sum over the nodes of `mask` and every channel of (a - b)^2, b = 0 when absent.
double masked_sum_sq(const std::array<std::vector<float>, 3>& a, const std::array<std::vector<float>, 3>* b,
                     const std::vector<bool>& mask) {
  double sum = 0;
  for (std::size_t c = 0; c < 3; ++c)
    for (std::size_t i = 0; i < a[c].size() && i < mask.size(); ++i)
      if (mask[i]) {
        const double d = static_cast<double>(a[c][i]) - (b && i < (*b)[c].size() ? (*b)[c][i] : 0.0f);
        sum += d * d;
      }
  return sum;
}

// sqrt(sum (got - ref)^2 / sum ref^2) over the nodes of `mask` and every channel: the error
// measure of docs/truth.md (a bake against the Monte Carlo reference).
double relative_l2(const std::array<std::vector<float>, 3>& ref, const std::array<std::vector<float>, 3>& got,
                   const std::vector<bool>& mask) {
  const double diff = masked_sum_sq(got, &ref, mask), norm = masked_sum_sq(ref, nullptr, mask);
  return norm > 0 ? std::sqrt(diff / norm) : (diff > 0 ? std::numeric_limits<double>::infinity() : 0.0);
}

// The nodes the L2 metric measures: occupied ones (density > 0 in the reference), else all.
std::vector<bool> occupied_nodes(const fs::path& ref_file, const DenseGridIn& like) {
  const DenseGridIn density = read_vdb_grid_dense(ref_file, "density");
  std::vector<bool> mask(like.values[0].size(), true);
  if (!(density.frame.dims == like.frame.dims) || density.frame.index_min != like.frame.index_min) return mask;
  std::size_t n = 0;
  for (std::size_t i = 0; i < mask.size(); ++i) n += (mask[i] = density.values[0][i] > 0.0f);
  if (n == 0) mask.assign(mask.size(), true);
  return mask;
}

bool has_grid(const fs::path& file, const std::string& grid) {
  const nlohmann::json info = inspect_vdb(file);  // kept: the loop reads into it
  for (const auto& g : info.at("grids"))
    if (g.value("name", "") == grid) return true;
  return false;
}

int compare_outputs(const CompareArgs& a) {
  const fs::path ref_dir = a.reference, other_dir = a.other;
  const nlohmann::json ref = output_manifest(ref_dir), other = output_manifest(other_dir);
  refuse_empty(ref, ref_dir);
  double worst = 0.0;
  int grids = 0;
  for (std::size_t mi = 0; mi < ref.at("models").size(); ++mi) {
    const nlohmann::json& model = ref["models"][mi];
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
    const std::size_t oi = static_cast<std::size_t>(it - other.at("models").begin());
    const fs::path fa = manifest_file(ref_dir, model.at("file"), "/models/" + std::to_string(mi) + "/file");
    const fs::path fb = manifest_file(other_dir, it->at("file"), "/models/" + std::to_string(oi) + "/file");
    std::vector<bool> mask;
    for (const auto& s : model.at("solutions")) {
      const std::string grid = s.at("grid");
      const DenseGridIn ref_grid = read_vdb_grid_dense(fa, grid), got_grid = read_vdb_grid_dense(fb, grid);
      if (const int j = base_solution_index(grid); j >= 0) {  // the checks relight and render apply
        check_base_solution_grid(ref_grid, j, ref_grid.frame, fa);
        check_base_solution_grid(got_grid, j, got_grid.frame, fb);
      }
      double d = 0;
      if (a.metric == "l2") {
        check_comparable(ref_grid, got_grid, fa, fb);
        if (mask.empty()) mask = occupied_nodes(fa, ref_grid);
        d = relative_l2(ref_grid.values, got_grid.values, mask);
        std::string own;
        if (has_grid(fa, grid + "_se")) {  // a Monte Carlo reference: its own noise, for scale
          const DenseGridIn se = read_vdb_grid_dense(fa, grid + "_se");
          const double norm = masked_sum_sq(ref_grid.values, nullptr, mask);
          char buf[96];
          std::snprintf(buf, sizeof buf, " (reference's standard error %.3g)",
                        norm > 0 ? std::sqrt(masked_sum_sq(se.values, nullptr, mask) / norm) : 0.0);
          own = buf;
        }
        std::printf("%s %s: relative L2 difference %.3g over the occupied nodes%s\n", name.c_str(), grid.c_str(), d,
                    own.c_str());
      } else {
        d = grid_difference(ref_grid, got_grid, fa, fb);
        std::printf("%s %s: max relative difference %.3g\n", name.c_str(), grid.c_str(), d);
      }
      keep_worst(worst, d);
      ++grids;
    }
  }
  if (grids == 0)
    throw_invalid("no model of this output has a solution grid to compare; allowed: a bake with at least one "
                  "solution",
                  {ref_dir.string(), {}, {}});
  const bool ok = worst <= a.tolerance;
  std::printf("largest over %d grid(s): %.3g (%s %g)\n", grids, worst, ok ? "within" : "ABOVE", a.tolerance);
  return ok ? 0 : 1;
}

std::string file_bytes(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw_io("cannot open", {file.string(), {}, {}});
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Bit for bit (docs/scale-out.md: a merged bake against a one-machine one): the manifests without
// their run record (run_record_fields), and per model the .vdb's grids (names, order, metadata,
// active voxels, every value's bits) and the .lbh bytes. Prints each difference; 1 when there is one.
int compare_exact(const CompareArgs& a) {
  const fs::path ref_dir = a.reference, other_dir = a.other;
  const nlohmann::json ref = output_manifest(ref_dir), other = output_manifest(other_dir);
  refuse_empty(ref, ref_dir);
  int differences = 0, grids = 0, lbh_files = 0;
  const auto differ = [&](const std::string& what) {
    if (++differences <= 20) std::printf("differs: %s\n", what.c_str());
  };
  const nlohmann::json patch = nlohmann::json::diff(without_run_record(ref), without_run_record(other));
  for (const auto& op : patch) differ("manifest " + op.value("path", std::string()) + " (" + op.value("op", "") + ")");
  if (!patch.empty()) {  // the files compared below are those both manifests name alike
    std::printf("%d difference(s) (manifests differ beyond their run record)\n", differences);
    return 1;
  }
  for (std::size_t mi = 0; mi < ref.at("models").size(); ++mi) {
    const nlohmann::json& model = ref["models"][mi];
    const std::string at = "/models/" + std::to_string(mi);
    const std::string name = model.at("name");
    if (model.at("file").is_string()) {
      const fs::path fa = manifest_file(ref_dir, model["file"], at + "/file");
      const fs::path fb = manifest_file(other_dir, other["models"][mi]["file"], at + "/file");
      nlohmann::json ia = inspect_vdb(fa), ib = inspect_vdb(fb);
      for (auto* info : {&ia, &ib}) info->erase("file");
      if (ia != ib) differ(name + ": .vdb grid list, metadata or active voxels");
      for (const auto& g : ia.value("grids", nlohmann::json::array())) {
        const std::string grid = g.value("name", "");
        const DenseGridIn ga = read_vdb_grid_dense(fa, grid), gb = read_vdb_grid_dense(fb, grid);
        ++grids;
        bool same = ga.type == gb.type && ga.frame.dims == gb.frame.dims && ga.frame.index_min == gb.frame.index_min &&
                    ga.frame.index_to_world == gb.frame.index_to_world;
        for (std::size_t c = 0; same && c < ga.values.size(); ++c)
          same = ga.values[c].size() == gb.values[c].size() &&
                 (ga.values[c].empty() ||  // memcmp takes no null pointer, even for 0 bytes
                  std::memcmp(ga.values[c].data(), gb.values[c].data(), ga.values[c].size() * sizeof(float)) == 0);
        if (!same) differ(name + " grid " + grid + ": values or lattice box");
      }
    }
    if (model.value("lbh_file", nlohmann::json()).is_string()) {
      ++lbh_files;
      if (file_bytes(manifest_file(ref_dir, model["lbh_file"], at + "/lbh_file")) !=
          file_bytes(manifest_file(other_dir, other["models"][mi]["lbh_file"], at + "/lbh_file")))
        differ(name + ": .lbh bytes");
    }
  }
  if (differences > 0) {
    std::printf("%d difference(s)\n", differences);
    return 1;
  }
  std::printf("identical: %d grid(s) bit for bit, %d .lbh file(s) byte for byte, manifests equal except their run "
              "record\n",
              grids, lbh_files);
  return 0;
}

int run_compare(const CompareArgs& a) {
  try {
    return a.exact ? compare_exact(a) : compare_outputs(a);
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
      "the largest relative difference, with values below 1e-6 of the grid's largest compared against that floor "
      "(--metric max), or the relative L2 difference over the occupied nodes (--metric l2: a bake against "
      "`lblight truth`). "
      "Exit 0 when every grid is within --tolerance, 1 when one is not, 2 when the outputs do not match up.");
  cmd->add_option("reference", args->reference, "Reference output directory (with manifest.json)")->required();
  cmd->add_option("other", args->other, "Output directory to compare against it")->required();
  cmd->add_option("--tolerance", args->tolerance, "Largest relative difference allowed (default 1e-5)")
      ->check(finite_range(0.0, 1e30));
  cmd->add_option("--metric", args->metric,
                  "max: the largest relative difference per value (bake against bake); l2: sqrt(sum (other - "
                  "reference)^2 / sum reference^2) over the reference's occupied nodes (a bake against "
                  "`lblight truth`, docs/truth.md)")
      ->check(CLI::IsMember({"max", "l2"}))
      ->capture_default_str();
  cmd->add_flag("--exact", args->exact,
                "Bit for bit instead (a merged bake against a one-machine one, docs/scale-out.md): every grid of "
                "every model (names, order, metadata, active voxels, values), the .lbh files byte for byte and the "
                "manifests except their run record (created, command, total_seconds, backend.description, "
                "peak_memory_bytes, seconds, residual_history times, encode_seconds); exit 1 on any difference");
  return {cmd, [args] { return run_compare(*args); }};
}

}  // namespace lblight::cli
