// lblight compress: the Vec3f grids of a .vdb into Haar-compressed sub-block streams (.lbh).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <sstream>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/compress/vdb_compress.h"
#include "lblight/core/error.h"

namespace fs = std::filesystem;

namespace lblight::cli {
namespace {

struct CompressArgs {
  std::string input, output, grids, coefficients = "auto";
  double threshold = -1;
  bool relative = false, json = false;
  int threads = 0;
};

std::string format_ratio(double r) {
  std::ostringstream s;
  s.precision(r < 10 ? 3 : 4);
  s << r << ":1";
  return s.str();
}

int run_compress(const CompressArgs& a) {
  const fs::path in = a.input;
  if (!fs::exists(in)) throw_invalid("no such file", {in.string(), {}, {}});
  if (in.extension() != ".vdb") throw_invalid("expected an OpenVDB file (.vdb)", {in.string(), {}, {}});
  fs::path out = a.output.empty() ? fs::path(in).replace_extension(".lbh") : fs::path(a.output);
  check_output_file(in, out, ".lbh");
  if (a.relative && a.threshold > 1)
    throw_invalid("--threshold " + std::to_string(a.threshold) + " with --relative; allowed: 0..1 (a fraction of each "
                  "solution's maximum)", {"--threshold", {}, {}});
  std::vector<std::string> grids;
  if (!a.grids.empty()) {
    std::stringstream ss(a.grids);
    std::string g;
    while (std::getline(ss, g, ',')) {
      if (g.empty()) continue;
      if (std::find(grids.begin(), grids.end(), g) != grids.end())
        throw_invalid("grid '" + g + "' is listed twice (a stream per grid name; decompress could not name both)",
                      {"--grids", {}, {}});
      grids.push_back(g);
    }
    if (grids.empty()) throw_invalid("no grid names in '" + a.grids + "'; give e.g. B00,B06", {"--grids", {}, {}});
  }
  const LbhFileContents c =
      compress_vdb(in, {a.threshold, a.relative, *parse_lbh_coefficients(a.coefficients)}, grids, usable_threads(a.threads));
  write_lbh(out, c.frame, c.solutions);

  nlohmann::json j;
  j["input"] = in.string();
  j["output"] = out.string();
  j["file_bytes"] = fs::file_size(out);
  j["solutions"] = nlohmann::json::array();
  double float_bytes = 0, stream_bytes = 0;
  Table t({"grid", "threshold", "coeffs", "ratio", "rms error", "max error", "max |value|", "fast blocks", "encode s"});
  for (const LbhEncoded& e : c.solutions) {
    const LbhStats& s = e.stats;
    float_bytes += static_cast<double>(s.float_rgb_bytes);
    stream_bytes += static_cast<double>(s.stream_bytes);
    nlohmann::json row = lbh_stats_json(e, out.filename().string());
    row["grid"] = e.name;
    j["solutions"].push_back(row);
    t.add({e.name, format_error(s.threshold), e.encoding == lbh::Encoding::Q8 ? "q8" : "f32", format_ratio(s.ratio), format_error(s.rms_error),
           format_error(s.max_abs_error), format_error(s.max_abs_value),
           std::to_string(s.fast_blocks) + "/" + std::to_string(s.blocks), format_seconds(s.encode_seconds)});
  }
  j["float_rgb_bytes"] = float_bytes;
  j["compressed_bytes"] = stream_bytes;
  j["ratio"] = float_bytes / stream_bytes;
  if (a.json) {
    std::cout << j.dump(2) << "\n";
  } else {
    std::cout << t.str() << c.solutions.size() << " solution(s): " << format_bytes(float_bytes) << " float RGB -> "
              << format_bytes(stream_bytes) << " compressed (" << format_ratio(float_bytes / stream_bytes) << "), file "
              << format_bytes(static_cast<double>(j["file_bytes"].get<std::uintmax_t>())) << ": " << out.string()
              << "\n";
  }
  return 0;
}

}  // namespace

Command add_compress_command(CLI::App& app, const GlobalOptions&) {
  auto args = std::make_shared<CompressArgs>();
  CLI::App* cmd = app.add_subcommand(
      "compress",
      "Compress the Vec3f grids (B00..B18 or light) of a .vdb into Haar sub-block streams (.lbh, docs/lbh-format.md): "
      "3^3 sub-blocks with a forward border, detail coefficients below the threshold in all three channels dropped. "
      "Prints ratio, RMS and max error per grid.");
  cmd->add_option("input", args->input, "Input .vdb (e.g. a bake's <model>.vdb)")->required();
  cmd->add_option("--threshold", args->threshold,
                  "Drop detail coefficients below this magnitude (absolute, or with --relative a fraction of each "
                  "grid's largest |value|); 0 is lossless")
      ->required()
      ->check(finite_range(0.0, 1e30));
  cmd->add_flag("--relative", args->relative, "Threshold relative to each grid's largest |value| (e.g. 0.01 = 1%)");
  cmd->add_option("--coefficients", args->coefficients,
                  "Storage of kept coefficients: f32 (every coefficient as 3 floats, as [Steele2009]), q8 (block average as "
                  "floats, details as 8-bit multiples of a step of threshold / 2, coarser only if the largest detail "
                  "needs it; about 2.5x smaller at the same threshold), auto (q8 when the threshold is > 0, else f32)")
      ->check(CLI::IsMember({"auto", "f32", "q8"}))
      ->capture_default_str();
  cmd->add_option("-o,--output", args->output, "Output .lbh (default: the input with extension .lbh)")
      ->check(kNonEmpty);
  cmd->add_option("--grids", args->grids, "Comma-separated grid names (default: every Vec3f grid)")->check(kNonEmpty);
  cmd->add_option("--threads", args->threads, "Encoder threads (0 = all cores)")->check(CLI::Range(0, 4096));
  cmd->add_flag("--json", args->json, "Print JSON instead of text");
  return {cmd, [args] { return run_compress(*args); }};
}

}  // namespace lblight::cli
