// lblight inspect: summarise a scene, a .vdb file or a bake output directory.
#include <CLI/CLI.hpp>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/core/error.h"
#include "lblight/core/input_file.h"
#include "lblight/core/system_info.h"
#include "lblight/pipeline/bake_output.h"
#include "lblight/pipeline/manifest.h"
#include "lblight/io/vdb_io.h"
#include "readers/lbh/lbh_reader.h"

namespace fs = std::filesystem;

namespace lblight::cli {
namespace {

struct InspectArgs {
  std::string path;
  bool json = false;
};

nlohmann::json scene_summary(const Scene& s) {
  nlohmann::json j;
  j["kind"] = "scene";
  j["file"] = s.file.string();
  j["name"] = s.name;
  j["hash"] = s.hash;
  j["lighting"] = s.lighting.mode == LightingMode::Base ? "base" : "static";
  j["solutions"] = s.lighting.solutions;
  j["solver"] = {{"iterations", to_string(s.solver.mode)}, {"tolerance", s.solver.tolerance},
                 {"precision", to_string(s.solver.precision)}};
  if (s.solver.mode == IterationMode::Fixed) j["solver"]["steps"] = s.solver.iterations;
  j["models"] = nlohmann::json::array();
  for (const ModelSpec& m : s.models) {
    nlohmann::json e{{"name", m.name}, {"source", to_string(m.density.type)}, {"margin", m.margin},
                     {"density_scale", m.density.density_scale}, {"material", material_json(m.material)},
                     {"wood_material", material_json(m.wood_material)}};
    if (m.density.type == SourceType::Procedural)
      e["procedural"] = {{"shape", m.density.procedural.shape}, {"resolution", m.density.procedural.resolution},
                         {"seed", m.density.procedural.seed}, {"size", m.density.procedural.size}};
    if (m.density.type == SourceType::Vdb) e["vdb"] = {{"path", m.density.vdb.path.string()}, {"grid", m.density.vdb.grid}};
    if (m.density.type == SourceType::Mesh)
      e["mesh"] = {{"path", m.density.mesh.path.string()}, {"resolution", m.density.mesh.resolution}};
    j["models"].push_back(e);
  }
  return j;
}

std::string scene_text(const nlohmann::json& j) {
  std::ostringstream s;
  s << "scene '" << j["name"].get<std::string>() << "' (" << j["file"].get<std::string>() << "), "
    << j["hash"].get<std::string>() << "\n";
  s << "lighting: " << j["lighting"].get<std::string>() << ", solver: " << j["solver"].dump() << "\n";
  Table t({"model", "source", "material", "wood material", "margin"});
  for (const auto& m : j["models"])
    t.add({m["name"], m["source"], m["material"]["name"], m["wood_material"]["name"], std::to_string(m["margin"].get<int>())});
  return s.str() + t.str();
}

std::string vdb_text(const nlohmann::json& j) {
  std::ostringstream s;
  s << j["file"].get<std::string>() << ": " << j["grids"].size() << " grid(s)\n";
  Table t({"grid", "type", "class", "active voxels", "bbox min", "bbox max", "voxel size"});
  for (const auto& g : j["grids"]) {
    t.add({g["name"], g["type"], g["class"], g.contains("active_voxels") ? g["active_voxels"].dump() : "?",
           g.contains("bbox_min") ? g["bbox_min"].dump() : "?", g.contains("bbox_max") ? g["bbox_max"].dump() : "?",
           g["voxel_size"].dump()});
  }
  s << t.str();
  for (const auto& g : j["grids"])
    if (!g["metadata"].empty()) s << "  " << g["name"].get<std::string>() << ": " << g["metadata"].dump() << "\n";
  return s.str();
}

// .lbh: validated by the reader library itself (the same checks a renderer runs).
nlohmann::json lbh_summary(const fs::path& file) {
  lbh::Stream s;
  check_host_memory(static_cast<double>(check_regular_file(file, ".lbh file")) * 2.0, "reading " + file.string(),
                    "inspect a smaller file", {file.string(), {}, {}});
  if (const lbh::Status st = s.open_file(file.string()); st != lbh::Status::Ok) {
    if (st == lbh::Status::IoError) throw_io(s.error());
    throw_invalid(s.error());
  }
  const lbh::Header& h = s.header();
  nlohmann::json j;
  j["kind"] = "lbh";
  j["file"] = file.string();
  j["version"] = h.version;
  j["file_bytes"] = h.file_bytes;
  j["dims"] = {h.dims[0], h.dims[1], h.dims[2]};
  j["index_min"] = {h.index_min[0], h.index_min[1], h.index_min[2]};
  j["sub_blocks"] = {h.blocks[0], h.blocks[1], h.blocks[2]};
  j["index_to_world"] = std::vector<double>(h.index_to_world, h.index_to_world + 16);
  const double nodes = static_cast<double>(h.dims[0]) * h.dims[1] * h.dims[2];
  double float_bytes = 0, stream_bytes = 0;
  j["solutions"] = nlohmann::json::array();
  for (std::size_t i = 0; i < s.solution_count(); ++i) {
    const lbh::SolutionInfo& in = s.info(i);
    nlohmann::json e;
    e["name"] = in.name;
    e["index"] = in.index;
    e["direction"] = {in.direction[0], in.direction[1], in.direction[2]};
    e["threshold"] = in.threshold;
    e["threshold_requested"] = {{"value", in.threshold_param}, {"relative", in.threshold_mode == 1}};
    e["max_abs_value"] = in.max_abs_value;
    e["blocks"] = in.block_count;
    e["fast_path_blocks"] = in.fast_blocks;
    e["coefficients"] = in.coeff_count;
    e["coefficient_encoding"] = in.encoding == lbh::Encoding::Q8 ? "q8" : "f32";
    if (in.encoding == lbh::Encoding::Q8) e["quant_step"] = in.quant_step;
    e["compressed_bytes"] = in.stream_bytes();
    e["float_rgb_bytes"] = nodes * 12;
    e["ratio"] = nodes * 12 / static_cast<double>(in.stream_bytes());
    e["max_abs_error"] = in.max_abs_error;
    e["rms_error"] = in.rms_error;
    float_bytes += nodes * 12;
    stream_bytes += static_cast<double>(in.stream_bytes());
    j["solutions"].push_back(e);
  }
  j["float_rgb_bytes"] = float_bytes;
  j["compressed_bytes"] = stream_bytes;
  j["ratio"] = float_bytes / stream_bytes;
  j["file_ratio"] = float_bytes / static_cast<double>(h.file_bytes);
  return j;
}

std::string lbh_text(const nlohmann::json& j) {
  std::ostringstream s;
  const auto& d = j["dims"];
  const auto& b = j["sub_blocks"];
  s << j["file"].get<std::string>() << ": .lbh v" << j["version"].get<int>() << ", " << d[0] << "x" << d[1] << "x"
    << d[2] << " lattice, " << b[0] << "x" << b[1] << "x" << b[2] << " sub-blocks, " << j["solutions"].size()
    << " solution(s), " << format_bytes(j["file_bytes"].get<double>()) << "\n";
  auto ratio = [](double r) {
    std::ostringstream o;
    o.precision(3);
    o << r << ":1";
    return o.str();
  };
  Table t({"grid", "index", "direction", "threshold", "blocks", "fast path", "coefficients", "stored as", "bytes", "ratio",
           "rms error", "max error"});
  for (const auto& e : j["solutions"]) {
    const auto dir = e["direction"];
    const double blocks = e["blocks"].get<double>();
    std::ostringstream fast;
    fast.precision(3);
    fast << e["fast_path_blocks"].get<std::uint64_t>() << " (" << 100.0 * e["fast_path_blocks"].get<double>() / blocks
         << "%)";
    t.add({e["name"], std::to_string(e["index"].get<int>()),
           format_direction({dir[0].get<int>(), dir[1].get<int>(), dir[2].get<int>()}),
           format_error(e["threshold"].get<double>()), e["blocks"].dump(), fast.str(), e["coefficients"].dump(),
           e["coefficient_encoding"] == "q8" ? "q8, step " + format_error(e["quant_step"].get<double>()) : "f32",
           format_bytes(e["compressed_bytes"].get<double>()), ratio(e["ratio"].get<double>()),
           format_error(e["rms_error"].get<double>()), format_error(e["max_abs_error"].get<double>())});
  }
  s << t.str();
  s << "total: " << format_bytes(j["float_rgb_bytes"].get<double>()) << " float RGB -> "
    << format_bytes(j["compressed_bytes"].get<double>()) << " (" << ratio(j["ratio"].get<double>())
    << "; with header and padding " << ratio(j["file_ratio"].get<double>()) << ")\n";
  return s.str();
}

nlohmann::json output_summary(const fs::path& dir) {
  nlohmann::json m = read_manifest(dir);
  m["kind"] = "output";
  m["missing_files"] = nlohmann::json::array();
  // "file" or "lbh_file" is null (or absent) when the scene did not ask for that file
  for (std::size_t i = 0; i < m["models"].size(); ++i)
    for (const char* key : {"file", "lbh_file"}) {
      const nlohmann::json& model = m["models"][i];
      if (!model.contains(key) || !model[key].is_string()) continue;
      const fs::path f = manifest_file(dir, model[key], "/models/" + std::to_string(i) + "/" + key);
      std::error_code ec;
      if (!fs::is_regular_file(f, ec)) m["missing_files"].push_back(model[key]);
    }
  return m;
}

// A manifest field as text, whatever its type: parse_manifest checked only what readers compute with.
std::string field(const nlohmann::json& obj, const char* key) {
  if (!obj.is_object() || !obj.contains(key)) return "?";
  const nlohmann::json& v = obj[key];
  return v.is_string() ? v.get<std::string>() : v.dump();
}
std::string seconds_field(const nlohmann::json& obj, const char* key) {
  return obj.contains(key) && obj[key].is_number() ? format_seconds(obj[key].get<double>()) : "?";
}

std::string output_text(const nlohmann::json& m, const fs::path& dir) {
  std::ostringstream s;
  const nlohmann::json none = nlohmann::json::object();
  const nlohmann::json& scene = m.contains("scene") ? m["scene"] : none;
  const nlohmann::json& backend = m.contains("backend") ? m["backend"] : none;
  s << dir.string() << ": lblight " << field(m, "lblight_version") << " output of scene '" << field(scene, "name")
    << "' (" << field(scene, "hash") << "), backend " << field(backend, "description") << ", "
    << field(backend, "precision") << ", " << seconds_field(m, "total_seconds") << " s\n";
  Table t({"model", "file", "solution", "direction", "iterations", "seconds", "error estimate"});
  for (const auto& model : m["models"]) {
    // the .vdb, or the .lbh when the scene wrote no .vdb ("file" is null then)
    const std::string file = model["file"].is_string()                                    ? model["file"].get<std::string>()
                             : model.contains("lbh_file") && model["lbh_file"].is_string() ? model["lbh_file"].get<std::string>()
                                                                                           : "-";
    for (const auto& sol : model["solutions"]) {
      std::string direction = "?";
      if (sol.contains("direction")) {
        const auto& d = sol["direction"];
        direction = format_direction({d[0].get<int>(), d[1].get<int>(), d[2].get<int>()});
      }
      const bool estimate = sol.contains("error_estimate") && sol["error_estimate"].is_number();
      t.add({model["name"], file, sol["grid"], direction, field(sol, "iterations"), seconds_field(sol, "seconds"),
             estimate ? format_error(sol["error_estimate"].get<double>()) : "n/a"});
    }
  }
  s << t.str();
  for (const auto& f : m["missing_files"]) s << "warning: listed file " << f.get<std::string>() << " is missing\n";
  return s.str();
}

int run_inspect(const InspectArgs& args) {
  const fs::path p = args.path;
  const Location where{p.string(), {}, {}};
  if (!fs::exists(p)) throw_invalid("no such file or directory", where);
  nlohmann::json j;
  std::string text;
  // a bake's manifest.json names its output directory: summarise that, not a scene
  const bool manifest = !fs::is_directory(p) && p.filename() == "manifest.json";
  if (fs::is_directory(p) || manifest) {
    const fs::path dir = !manifest ? p : p.has_parent_path() ? p.parent_path() : fs::path(".");
    if (!fs::exists(dir / "manifest.json"))
      throw_invalid("directory holds no manifest.json; allowed: a scene .json, a .vdb file or an lblight output "
                    "directory",
                    where);
    j = output_summary(dir);
    text = output_text(j, dir);
  } else if (p.extension() == ".json") {
    j = scene_summary(load_scene(p));
    text = scene_text(j);
  } else if (p.extension() == ".vdb") {
    j = inspect_vdb(p);
    j["kind"] = "vdb";
    text = vdb_text(j);
  } else if (p.extension() == ".lbh") {
    j = lbh_summary(p);
    text = lbh_text(j);
  } else {
    throw_invalid("unknown file type '" + p.extension().string() +
                      "'; allowed: a scene .json, a .vdb or .lbh file or an lblight output directory",
                  where);
  }
  std::cout << (args.json ? j.dump(2) + "\n" : text);
  return j.contains("missing_files") && !j["missing_files"].empty() ? 1 : 0;
}

}  // namespace

Command add_inspect_command(CLI::App& app, const GlobalOptions&) {
  auto args = std::make_shared<InspectArgs>();
  CLI::App* cmd = app.add_subcommand(
      "inspect", "Summarise a scene file (.json), an OpenVDB file (.vdb: grids, types, boxes, metadata), a "
                 "Haar-compressed stream (.lbh: validated; sizes, ratio, fast-path blocks, errors) or a bake output "
                 "directory or its manifest.json (solutions, iterations, times, error estimates).");
  cmd->add_option("path", args->path, "Scene, .vdb or .lbh file, or output directory")->required();
  cmd->add_flag("--json", args->json, "Print JSON instead of text");
  return {cmd, [args] { return run_inspect(*args); }};
}

}  // namespace lblight::cli
