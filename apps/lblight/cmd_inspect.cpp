// lblight inspect: summarise a scene, a .vdb file or a bake output directory.
#include <CLI/CLI.hpp>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/core/error.h"
#include "lblight/io/bake_output.h"
#include "lblight/io/vdb_io.h"

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

nlohmann::json output_summary(const fs::path& dir) {
  std::ifstream in(dir / "manifest.json");
  nlohmann::json m;
  try {
    in >> m;
  } catch (const nlohmann::json::exception& e) {
    throw_invalid(std::string("manifest.json is not valid JSON: ") + e.what(), {(dir / "manifest.json").string(), {}, {}});
  }
  m["kind"] = "output";
  m["missing_files"] = nlohmann::json::array();
  for (const auto& model : m.value("models", nlohmann::json::array()))
    if (!fs::exists(dir / model.value("file", ""))) m["missing_files"].push_back(model.value("file", ""));
  return m;
}

std::string output_text(const nlohmann::json& m, const fs::path& dir) {
  std::ostringstream s;
  s << dir.string() << ": lblight " << m.value("lblight_version", "?") << " output of scene '"
    << m["scene"].value("name", "?") << "' (" << m["scene"].value("hash", "?") << "), backend "
    << m["backend"].value("description", "?") << ", " << m["backend"].value("precision", "?") << ", "
    << format_seconds(m.value("total_seconds", 0.0)) << " s\n";
  Table t({"model", "file", "solution", "direction", "iterations", "seconds", "error estimate"});
  for (const auto& model : m["models"])
    for (const auto& sol : model["solutions"]) {
      const auto d = sol["direction"];
      t.add({model["name"], model["file"], sol["grid"],
             format_direction({d[0].get<int>(), d[1].get<int>(), d[2].get<int>()}), sol["iterations"].dump(),
             format_seconds(sol["seconds"].get<double>()),
             sol["error_estimate"].is_null() ? "n/a" : format_error(sol["error_estimate"].get<double>())});
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
  if (fs::is_directory(p)) {
    if (!fs::exists(p / "manifest.json"))
      throw_invalid("directory holds no manifest.json; allowed: a scene .json, a .vdb file or an lblight output "
                    "directory",
                    where);
    j = output_summary(p);
    text = output_text(j, p);
  } else if (p.extension() == ".json") {
    j = scene_summary(load_scene(p));
    text = scene_text(j);
  } else if (p.extension() == ".vdb") {
    j = inspect_vdb(p);
    j["kind"] = "vdb";
    text = vdb_text(j);
  } else {
    throw_invalid("unknown file type '" + p.extension().string() +
                      "'; allowed: a scene .json, a .vdb file or an lblight output directory",
                  where);
  }
  std::cout << (args.json ? j.dump(2) + "\n" : text);
  return j.contains("missing_files") && !j["missing_files"].empty() ? 1 : 0;
}

}  // namespace

Command add_inspect_command(CLI::App& app, const GlobalOptions&) {
  auto args = std::make_shared<InspectArgs>();
  CLI::App* cmd = app.add_subcommand(
      "inspect", "Summarise a scene file (.json), an OpenVDB file (.vdb: grids, types, boxes, metadata) or a bake "
                 "output directory (manifest: solutions, iterations, times, error estimates).");
  cmd->add_option("path", args->path, "Scene, .vdb file or output directory")->required();
  cmd->add_flag("--json", args->json, "Print JSON instead of text");
  return {cmd, [args] { return run_inspect(*args); }};
}

}  // namespace lblight::cli
