#include "lblight/pipeline/render_bake.h"

#include <algorithm>

#include "lblight/core/error.h"
#include "lblight/io/vdb_io.h"
#include "lblight/pipeline/manifest.h"
#include "lblight/scene/json_reader.h"
#include "lblight/scene/material.h"

namespace fs = std::filesystem;

namespace lblight {
namespace {

std::array<OpticalParams, 3> from_json(const nlohmann::json& m, const std::string& file, const std::string& at) {
  std::array<OpticalParams, 3> out{};
  for (const char* key : {"sigma_a", "sigma_s", "g"})
    if (!m.contains(key) || !m[key].is_array() || m[key].size() != 3)
      throw_invalid(std::string("material '") + key + "' must be 3 numbers", {file, at + "/" + key, {}});
  for (int c = 0; c < 3; ++c) {
    out[c].sigma_a = m["sigma_a"][c].get<double>();
    out[c].sigma_s = m["sigma_s"][c].get<double>();
    out[c].g = m["g"][c].get<double>();
    if (!(out[c].sigma_a >= 0 && out[c].sigma_s >= 0 && std::fabs(out[c].g) <= 1))
      throw_invalid("material values out of range", {file, at, {}});
  }
  return out;
}

std::array<OpticalParams, 3> from_preset(const std::string& name) {
  const std::optional<Material> m = material_preset(name);
  if (!m) {
    std::string list;
    for (const std::string& n : material_preset_names()) list += (list.empty() ? "" : ", ") + n;
    throw_invalid("unknown material preset '" + name + "'; allowed: " + list);
  }
  return m->channel;
}

// `grid` copied into `frame` by index coordinate (0 where it has no value).
std::vector<float> onto(const DenseFrame& frame, const DenseGridIn& grid, int channel) {
  std::vector<float> out(frame.dims.count(), 0.0f);
  const Dims& s = grid.frame.dims;
  const std::vector<float>& v = grid.values[static_cast<std::size_t>(channel)].empty() ? grid.values[0]
                                                                                       : grid.values[static_cast<std::size_t>(channel)];
  for (int z = 0; z < s.nz; ++z)
    for (int y = 0; y < s.ny; ++y)
      for (int x = 0; x < s.nx; ++x) {
        const int i = x + grid.frame.index_min[0] - frame.index_min[0], j = y + grid.frame.index_min[1] - frame.index_min[1],
                  k = z + grid.frame.index_min[2] - frame.index_min[2];
        if (i < 0 || j < 0 || k < 0 || i >= frame.dims.nx || j >= frame.dims.ny || k >= frame.dims.nz) continue;
        out[frame.dims.index(i, j, k)] = v[s.index(x, y, z)];
      }
  return out;
}

bool has_grid(const nlohmann::json& inspected, const std::string& name) {
  for (const auto& g : inspected.at("grids"))
    if (g.at("name") == name) return true;
  return false;
}

}  // namespace

RenderVolume load_render_volume(const RenderSource& src, const RelightRequest& sun, const RunContext& ctx) {
  fs::path vdb = src.input;
  nlohmann::json manifest;
  std::string manifest_file_name;
  std::error_code ec;
  if (fs::is_directory(vdb, ec)) {
    manifest = read_manifest(vdb);
    manifest_file_name = (vdb / "manifest.json").string();
    if (manifest.contains("forest"))
      throw_invalid("a forest bake: relight it into one volume first (lblight relight " + src.input.string() +
                        " -o forest-light.vdb) and render that with --material",
                    {src.input.string(), {}, {}});
    std::vector<std::string> names;
    for (const auto& m : manifest["models"])
      if (m["file"].is_string()) names.push_back(m["name"].get<std::string>());
    std::string model = src.model;
    if (model.empty()) {
      if (names.size() != 1)
        throw_invalid("the bake holds " + std::to_string(names.size()) + " models; choose one with --model", {src.input.string(), {}, {}});
      model = names[0];
    }
    if (std::find(names.begin(), names.end(), model) == names.end())
      throw_invalid("no model '" + model + "' in this bake", {src.input.string(), {}, {}});
    vdb = manifest_file(src.input, model + ".vdb", "/models");
  } else if (fs::exists(vdb.parent_path() / "manifest.json", ec)) {
    manifest = read_manifest(vdb.parent_path());
    manifest_file_name = (vdb.parent_path() / "manifest.json").string();
  }
  if (!fs::exists(vdb, ec)) throw_invalid("no such file", {vdb.string(), {}, {}});
  const nlohmann::json inspected = inspect_vdb(vdb, ctx);
  if (!has_grid(inspected, "density")) throw_invalid("no grid 'density': not an lblight bake or relit volume", {vdb.string(), {}, {}});
  RenderVolume v;
  if (!src.grid.empty()) {
    if (!has_grid(inspected, src.grid)) {
      std::string names;
      for (const auto& g : inspected.at("grids")) names += (names.empty() ? "" : ", ") + g.at("name").get<std::string>();
      throw_invalid("no grid '" + src.grid + "' in this file; it has: " + names, {vdb.string(), {}, {}});
    }
    const DenseGridIn density = read_vdb_grid_dense(vdb, "density", ctx);
    v.frame = density.frame;
    v.density = onto(v.frame, density, 0);
    const DenseGridIn shown = read_vdb_grid_dense(vdb, src.grid, ctx);
    const int channels = shown.values[1].empty() ? 1 : 3;
    v.field.assign(v.frame.dims.count(), 0.0f);
    for (int c = 0; c < channels; ++c) {
      const std::vector<float> part = onto(v.frame, shown, c);
      for (std::size_t i = 0; i < part.size(); ++i) v.field[i] += part[i] / static_cast<float>(channels);
    }
    volume_voxel_size(v.frame);
    return v;
  }
  const bool relit = has_grid(inspected, "light") && !has_grid(inspected, "B00") && !has_grid(inspected, "B06");
  if (relit) {  // the LB model's delta-M scaling, as relight recorded it from the bake
    const nlohmann::json& meta = inspected.at("file_metadata");
    v.delta_m = meta.contains("lblight_delta_m") && meta["lblight_delta_m"].is_boolean() && meta["lblight_delta_m"].get<bool>();
  }
  if (relit && src.light) {
    // The renderer removes the unscattered sun from the light: both must be for the same sun.
    const nlohmann::json& meta = inspected.at("file_metadata");
    if (meta.contains("lblight_sun_elevation") && meta.contains("lblight_sun_azimuth") && meta.contains("lblight_intensity")) {
      const double e = meta["lblight_sun_elevation"].get<double>(), az = meta["lblight_sun_azimuth"].get<double>();
      const Vec3d t = toward_sun_from_angles(e, az);
      const double d = std::fabs(t.x - sun.toward_sun.x) + std::fabs(t.y - sun.toward_sun.y) + std::fabs(t.z - sun.toward_sun.z);
      if (d > 1e-6 || std::fabs(meta["lblight_intensity"].get<double>() - sun.intensity) > 1e-9 * (1 + sun.intensity))
        throw_invalid("this volume was relit for a sun at elevation " + message_number(e) + ", azimuth " + message_number(az) +
                          ", intensity " + message_number(meta["lblight_intensity"].get<double>()) +
                          "; render it with the same --sun-elevation, --sun-azimuth and --intensity (the renderer "
                          "takes the unscattered sun out of the light), or use --term direct",
                      {vdb.string(), {}, {}});
    }
  }
  if (relit || !src.light) {
    const DenseGridIn light = read_vdb_grid_dense(vdb, relit ? "light" : "density", ctx);
    v.frame = light.frame;
    if (relit && src.light) {
      for (int c = 0; c < 3; ++c) v.light[c] = onto(v.frame, light, c);
      if (src.scattering == Scattering::PhaseP1 && has_grid(inspected, "light_flux_r"))
        for (int c = 0; c < 3; ++c) {
          const DenseGridIn f = read_vdb_grid_dense(vdb, std::string("light_flux_") + "rgb"[c], ctx);
          if (f.values[1].empty()) throw_invalid("grid " + f.name + " is not a vector grid", {vdb.string(), f.name, {}});
          for (int a = 0; a < 3; ++a) v.flux[c][a] = onto(v.frame, f, a);
        }
    }
    v.density = onto(v.frame, read_vdb_grid_dense(vdb, "density", ctx), 0);
    if (has_grid(inspected, "brown")) {
      const std::vector<float> brown = onto(v.frame, read_vdb_grid_dense(vdb, "brown", ctx), 0);
      v.material.resize(brown.size());
      for (std::size_t i = 0; i < brown.size(); ++i) v.material[i] = brown[i] > 0.5f ? kMaterialWood : kMaterialMedium;
    }
  } else {
    const RelitModel r = relight_model(vdb, sun, ctx);
    v.frame = r.frame;
    v.density = r.density;
    v.light = r.light;
    if (src.scattering == Scattering::PhaseP1) v.flux = r.flux;
    if (has_grid(inspected, "brown")) {
      const DenseGridIn brown = read_vdb_grid_dense(vdb, "brown", ctx);
      v.material.resize(brown.values[0].size());
      for (std::size_t i = 0; i < v.material.size(); ++i)
        v.material[i] = brown.values[0][i] > 0.5f ? kMaterialWood : kMaterialMedium;
    }
  }
  // Materials: the caller's presets, else the manifest's entry for this file.
  bool known = false;
  if (src.material) {
    v.materials[0] = from_preset(*src.material);
    const std::optional<Material> m = material_preset(*src.material);
    v.materials[1] = src.wood_material ? from_preset(*src.wood_material) : default_wood_for(*m).channel;
    known = true;
  } else if (!manifest.is_null()) {
    for (std::size_t i = 0; i < manifest["models"].size(); ++i) {
      const nlohmann::json& m = manifest["models"][i];
      if (!m["file"].is_string() || m["file"].get<std::string>() != vdb.filename().string()) continue;
      const std::string at = "/models/" + std::to_string(i) + "/materials";
      if (!m.contains("materials") || !m["materials"].contains("medium")) break;
      v.materials[0] = from_json(m["materials"]["medium"], manifest_file_name, at + "/medium");
      v.materials[1] = m["materials"].contains("wood") ? from_json(m["materials"]["wood"], manifest_file_name, at + "/wood") : v.materials[0];
      known = true;
      v.delta_m = solved_with_delta_m(m);
    }
  }
  if (!known) {  // the file's own description (docs/output-format.md): a .vdb away from its manifest
    for (const auto& g : inspected.at("grids")) {
      if (g.value("name", std::string()) != "density" || !g.contains("metadata")) continue;
      const nlohmann::json& meta = g["metadata"];
      if (!meta.contains("lblight_material_medium") || !meta["lblight_material_medium"].is_string()) break;
      const auto material = [&](const char* key) {
        return from_json(JsonReader::parse_strict(meta[key].get<std::string>(), vdb.string()), vdb.string(),
                         std::string("density metadata ") + key);
      };
      v.materials[0] = material("lblight_material_medium");
      v.materials[1] = meta.contains("lblight_material_wood") && meta["lblight_material_wood"].is_string()
                           ? material("lblight_material_wood")
                           : v.materials[0];
      if (!relit && meta.contains("lblight_delta_m") && meta["lblight_delta_m"].is_boolean())
        v.delta_m = meta["lblight_delta_m"].get<bool>();
      known = true;
    }
  }
  if (!known)
    throw_invalid("the materials of this volume are not known: name them with --material (and --wood-material), "
                  "or render the bake folder",
                  {vdb.string(), {}, {}});
  // Moments: never a silently isotropic picture from a bake without them.
  if (src.light && src.scattering == Scattering::PhaseP1 && !v.light[0].empty() && v.flux[0][0].empty())
    throw_invalid(std::string("this volume has no flux grids (") + (relit ? "light_flux_r/_g/_b" : "B.._flux_r/_g/_b") +
                      "), which phase-aware rendering needs: re-bake with \"output\": {\"moments\": true} (the default)" + (relit ? " and relight again" : "") +
                      ", or render with --scattering isotropic (the scattered light in-scattered as if isotropic)",
                  {vdb.string(), {}, {}});
  volume_voxel_size(v.frame);  // refuses rotated or stretched voxels up front
  return v;
}

}  // namespace lblight
