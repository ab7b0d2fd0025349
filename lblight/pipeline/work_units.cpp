#include "lblight/pipeline/work_units.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <optional>
#include <map>
#include <set>

#include <spdlog/spdlog.h>

#include "lblight/core/error.h"
#include "lblight/core/hash.h"
#include "lblight/core/system_info.h"
#include "lblight/core/version.h"
#include "lblight/io/output_dir.h"
#include "lblight/io/run_paths.h"
#include "lblight/pipeline/bake_output.h"
#include "lblight/pipeline/manifest.h"
#include "lblight/solve/ambient_sum.h"
#include "lblight/solve/bake.h"

namespace fs = std::filesystem;

namespace lblight {
namespace {

template <class T>
std::uint64_t hash_array(const std::vector<T>& v, std::uint64_t h) {
  return fnv1a64(std::string_view(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T)), h);
}

std::string checksum_text(std::uint64_t h) { return "fnv1a64:" + hex64(h); }

// Reads `from` in blocks, hashing it, and writes each block to `to` unless `to` is empty.
std::string hash_and_copy(const fs::path& from, const fs::path& to) {
  std::ifstream in(from, std::ios::binary);
  if (!in) throw_io(std::string("cannot open: ") + std::strerror(errno), {from.string(), {}, {}});
  std::ofstream out;
  if (!to.empty()) {
    out.open(to, std::ios::binary);
    if (!out) throw_io(std::string("cannot create: ") + std::strerror(errno), {to.string(), {}, {}});
  }
  std::vector<char> block(1 << 20);
  std::uint64_t h = fnv1a64({});
  while (in) {
    in.read(block.data(), static_cast<std::streamsize>(block.size()));
    const auto n = static_cast<std::size_t>(in.gcount());
    h = fnv1a64(std::string_view(block.data(), n), h);
    if (!to.empty() && n > 0) out.write(block.data(), static_cast<std::streamsize>(n));
  }
  if (in.bad()) throw_io("cannot read", {from.string(), {}, {}});
  if (!to.empty()) {
    out.flush();
    if (!out) throw_io("cannot write (disk full?)", {to.string(), {}, {}});
  }
  return checksum_text(h);
}

// The files a manifest names (its models' "file" and "lbh_file", a unit's "totals"), each once.
std::vector<std::pair<std::string, std::string>> named_files(const nlohmann::json& manifest) {
  std::vector<std::pair<std::string, std::string>> files;  // name, JSON pointer
  std::set<std::string> seen;
  const auto add = [&](const nlohmann::json& f, const std::string& pointer) {
    if (f.is_string() && seen.insert(f.get<std::string>()).second) files.push_back({f.get<std::string>(), pointer});
  };
  const nlohmann::json& models = manifest.at("models");
  for (std::size_t i = 0; i < models.size(); ++i)
    for (const char* key : {"file", "lbh_file", "nanovdb_file"})
      if (models[i].contains(key)) add(models[i][key], "/models/" + std::to_string(i) + "/" + key);
  for (const char* key : {"totals", "flux"}) {  // a unit's raw totals and flux (bake_output.h)
    const nlohmann::json raw = manifest.value("unit", nlohmann::json::object()).value(key, nlohmann::json());
    if (raw.is_object())
      for (const auto& [grid, f] : raw.items()) add(f, std::string("/unit/") + key + "/" + grid);
  }
  return files;
}

// PlanOverrides as a unit records them (a merge plans a model baked in parts again with them).
nlohmann::json plan_overrides_json(const PlanOverrides& ov) {
  nlohmann::json j = nlohmann::json::object();
  if (ov.solutions) j["solutions"] = *ov.solutions;
  if (ov.mode) j["mode"] = static_cast<int>(*ov.mode);
  j["iterations"] = ov.iterations;
  if (ov.tolerance) j["tolerance"] = *ov.tolerance;
  if (ov.precision) j["precision"] = static_cast<int>(*ov.precision);
  if (ov.method) j["method"] = static_cast<int>(*ov.method);
  if (ov.state) j["state"] = to_string(*ov.state);
  return j;
}

// The fields by which parts of one bake agree (besides the units list): what a one-machine bake
// writes once for all models.
const std::vector<std::string> kSharedFields = {"/lblight_version", "/manifest_format", "/scene", "/lighting",
                                                 "/backend/name", "/backend/precision", "/units", "/reference"};

std::string scene_words(const nlohmann::json& m) {
  const nlohmann::json& s = m.value("scene", nlohmann::json::object());
  return "scene '" + s.value("name", std::string("?")) + "' (" + s.value("file", std::string("?")) + ", " +
         s.value("hash", std::string("no hash")) + ")";
}

std::string join(const std::vector<std::string>& v, const std::string& sep = ", ") {
  std::string s;
  for (const std::string& e : v) s += (s.empty() ? "" : sep) + e;
  return s;
}

// Removes (object member) or nulls (array element) what `pointer` names below `at`.
void drop(nlohmann::json& at, const std::vector<std::string>& parts, std::size_t k) {
  if (k + 1 == parts.size()) {
    if (at.is_object()) at.erase(parts[k]);
    if (at.is_array() && parts[k] != "*") {
      const std::size_t i = std::stoul(parts[k]);
      if (i < at.size()) at[i] = nullptr;
    }
    return;
  }
  if (parts[k] == "*") {
    if (at.is_array())
      for (auto& e : at) drop(e, parts, k + 1);
  } else if (at.is_object() && at.contains(parts[k])) {
    drop(at[parts[k]], parts, k + 1);
  } else if (at.is_array() && std::all_of(parts[k].begin(), parts[k].end(), ::isdigit)) {
    const std::size_t i = std::stoul(parts[k]);
    if (i < at.size()) drop(at[i], parts, k + 1);
  }
}

}  // namespace

PlanOverrides plan_overrides_from_json(const nlohmann::json& j) {
  PlanOverrides ov;
  if (j.contains("solutions")) ov.solutions = j["solutions"].get<std::vector<int>>();
  if (j.contains("mode")) ov.mode = static_cast<IterationMode>(j["mode"].get<int>());
  ov.iterations = j.value("iterations", 0);
  if (j.contains("tolerance")) ov.tolerance = j["tolerance"].get<double>();
  if (j.contains("precision")) ov.precision = static_cast<Precision>(j["precision"].get<int>());
  if (j.contains("method")) ov.method = static_cast<SolverMethod>(j["method"].get<int>());
  if (j.contains("state")) ov.state = parse_state_layout(j["state"].get<std::string>());
  return ov;
}

UnitSpec parse_unit(const std::string& text) {
  const std::size_t colon = text.find(':');
  UnitSpec u{text.substr(0, colon), {}};
  if (u.name.empty()) throw_invalid("'" + text + "' names no unit; allowed: MODEL or MODEL:SOLUTIONS", {"--only", {}, {}});
  if (colon != std::string::npos) u.solutions = parse_solution_list(text.substr(colon + 1), {"--only", {}, {}});
  return u;
}

std::string unit_hash(const BakePlan& plan, const ModelPlan& mp, const std::string& backend_name) {
  nlohmann::json in;
  in["lblight"] = kVersion;
  in["manifest_format"] = kManifestFormat;
  in["scene_hash"] = plan.scene->hash;
  in["unit"] = mp.spec->name;
  in["backend"] = backend_name;
  in["precision"] = to_string(plan.precision);
  in["lattice"] = lattice_json(mp);
  in["materials"] = {material_json(mp.spec->material), material_json(mp.spec->wood_material)};
  in["material_count"] = mp.lattice.material_count;
  nlohmann::json sols = nlohmann::json::array();
  for (const SolutionPlan& s : mp.solutions) sols.push_back({s.index, s.boundary, s.derived});
  in["solutions"] = sols;
  const StepPolicy& st = mp.steps;
  in["steps"] = {to_string(st.mode), to_string(st.method), st.fixed_steps, st.min_steps, st.max_steps,
                 st.check_interval, st.tolerance, to_string(st.precision)};
  std::uint64_t h = fnv1a64(in.dump());
  h = hash_array(mp.lattice.density, h);
  h = hash_array(mp.lattice.material, h);
  return checksum_text(h);
}

nlohmann::json unit_record(const BakePlan& plan, const ModelPlan& mp, const std::string& backend_name,
                           const PlanOverrides& overrides, const std::vector<int>& solutions) {
  nlohmann::json u = {{"name", mp.spec->name}, {"hash", unit_hash(plan, mp, backend_name)},
                      {"units", lattice_names(*plan.scene)}};
  if (solutions.empty()) return u;
  // A share of the model: its own hash covers which solutions it holds.
  std::vector<int> solved;
  for (const SolutionPlan& s : mp.solutions)
    if (!s.derived) solved.push_back(s.index);
  u["model_hash"] = u["hash"];
  u["model_solutions"] = solved;
  u["solutions"] = solutions;
  u["plan_overrides"] = plan_overrides_json(overrides);
  u["hash"] = checksum_text(fnv1a64(nlohmann::json(solutions).dump(), fnv1a64(u["model_hash"].get<std::string>())));
  return u;
}

BakePlan unit_plan(BakePlan& full, std::size_t index) {
  BakePlan sub;
  sub.scene = full.scene;
  sub.precision = full.precision;
  ModelPlan& mp = full.models.at(index);
  // As make_plan with `only`: a scene model's unit of a forest with coarse lattices has no forest.
  if (full.forest && (mp.role != PlanRole::Model || !full.forest->coarse)) sub.forest = full.forest;
  sub.models.push_back(std::move(mp));
  return sub;
}

std::string file_checksum(const fs::path& file) { return hash_and_copy(file, {}); }

nlohmann::json file_checksums(const fs::path& dir, const nlohmann::json& manifest) {
  nlohmann::json files = nlohmann::json::object();
  for (const auto& [name, pointer] : named_files(manifest)) {
    const fs::path p = dir / name;
    std::error_code ec;
    const auto bytes = fs::file_size(p, ec);
    if (ec) throw_io("cannot read its size: " + ec.message(), {p.string(), {}, {}});
    files[name] = {{"bytes", bytes}, {"checksum", file_checksum(p)}};
  }
  return files;
}

PartCheck check_part(const fs::path& dir, const std::string& name, const std::string& hash, bool verify) {
  PartCheck c;
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(dir, ec)) || (fs::is_directory(dir, ec) && fs::is_empty(dir, ec))) return c;
  c.state = PartState::Other;
  if (!fs::is_directory(dir, ec)) {
    c.why = "not a folder";
    return c;
  }
  if (!fs::exists(dir / "manifest.json", ec)) {
    c.why = "no manifest.json: not a finished partial output";
    return c;
  }
  try {
    c.manifest = read_manifest(dir);
  } catch (const Error& e) {
    c.why = "damaged: " + std::string(e.what());
    return c;
  }
  const nlohmann::json& m = c.manifest;
  const nlohmann::json u = m.value("unit", nlohmann::json());
  if (!u.is_object() || !u.value("name", nlohmann::json()).is_string() ||
      !u.value("hash", nlohmann::json()).is_string() || !u.value("units", nlohmann::json()).is_array() ||
      !u.value("files", nlohmann::json()).is_object()) {
    c.why = "not a partial output (its manifest has no \"unit\" object with name, hash, units and files: a whole "
            "bake, or another tool's)";
    return c;
  }
  const std::string unit = u["name"];
  if (!name.empty() && unit != name) {
    c.why = "holds unit '" + unit + "', not '" + name + "'";
    return c;
  }
  if (!hash.empty() && u["hash"] != hash) {
    c.why = "its inputs hash " + u["hash"].get<std::string>() + " is not this bake's " + hash +
            " (another scene, model grid, solver settings, backend or lblight version)";
    return c;
  }
  if (m["models"].size() != 1 || m["models"][0]["name"] != unit) {
    c.why = "damaged: its manifest must list exactly the model '" + unit + "'";
    return c;
  }
  try {
    const auto files = named_files(m);
    if (files.size() != u["files"].size()) throw_invalid("its files and unit.files do not match", {(dir / "manifest.json").string(), "/unit/files", {}});
    for (const auto& [file, pointer] : files) {
      const nlohmann::json rec = u["files"].value(file, nlohmann::json());
      if (!rec.is_object() || !rec.value("bytes", nlohmann::json()).is_number_unsigned() ||
          !rec.value("checksum", nlohmann::json()).is_string())
        throw_invalid("no size and checksum for " + file, {(dir / "manifest.json").string(), "/unit/files", {}});
      const fs::path p = manifest_file(dir, file, pointer);
      const auto bytes = fs::file_size(p, ec);
      if (ec) throw_invalid("missing " + file, {p.string(), {}, {}});
      if (bytes != rec["bytes"].get<std::uintmax_t>())
        throw_invalid(file + " has " + std::to_string(bytes) + " bytes, not the " + std::to_string(rec["bytes"].get<std::uintmax_t>()) +
                          " written (cut short or changed)",
                      {p.string(), {}, {}});
      if (verify && file_checksum(p) != rec["checksum"])
        throw_invalid(file + " does not match its checksum (changed or damaged after the bake)", {p.string(), {}, {}});
    }
  } catch (const Error& e) {
    c.why = "damaged: " + std::string(e.what());
    return c;
  }
  c.state = PartState::Done;
  return c;
}

namespace {

struct Part {
  fs::path dir;
  nlohmann::json manifest;
  bool owned = false;  // assembled by this merge: its files are moved, and its folder removed
  const nlohmann::json& unit() const { return manifest["unit"]; }
  bool split() const { return unit().contains("solutions"); }
};

[[noreturn]] void refuse(const fs::path& dir, const std::string& why, const std::string& pointer = {}) {
  throw_invalid("refused part " + dir.string() + ": " + why + "; nothing was merged",
                {(dir / "manifest.json").string(), pointer, {}});
}

double number_or_inf(const nlohmann::json& v) {
  return v.is_number() ? v.get<double>() : std::numeric_limits<double>::infinity();
}

// A solution as a bake handed it to its output: the manifest row (which keeps every number it
// was written from; null for what was not finite) and its totals.
SolutionResult solution_from_row(const nlohmann::json& row, const SolutionPlan& plan) {
  SolutionResult r;
  r.plan = plan;
  r.iterations = row.at("iterations");
  r.seconds = row.at("seconds");
  r.error_estimate = number_or_inf(row.at("error_estimate"));
  r.error_estimate_max = number_or_inf(row.at("error_estimate_max"));
  r.converged = row.at("converged");
  if (row.contains("krylov")) {
    r.krylov_iterations = row["krylov"].at("iterations");
    r.krylov_residual = number_or_inf(row["krylov"].at("relative_residual"));
  }
  if (row.contains("photons")) r.photons = row["photons"];
  for (const nlohmann::json& h : row.at("residual_history")) {
    CheckPoint c;
    c.step = h.at(0);
    c.seconds = number_or_inf(h.at(1));
    c.change_l2 = number_or_inf(h.at(2));
    c.error_estimate = number_or_inf(h.at(3));
    c.error_estimate_max = number_or_inf(h.at(4));
    r.history.push_back(c);
  }
  return r;
}

// The scene the parts were baked from, under the path they record (their manifests must agree
// with a one-machine bake's); --scene where that path does not load from here.
Scene scene_of(const Part& part, const MergeOptions& opt) {
  const std::string recorded = part.manifest["scene"].value("file", "");
  const std::string hash = part.manifest["scene"].value("hash", "");
  std::error_code ec;
  Scene scene = load_scene(fs::exists(recorded, ec) || opt.scene_file.empty() ? recorded : opt.scene_file);
  scene.file = recorded;
  if (scene.hash != hash)
    refuse(part.dir, "its scene " + recorded + " now has the hash " + scene.hash + ", not the " + hash +
                         " it was baked with: the model cannot be assembled from it",
           "/scene/hash");
  return scene;
}

// A unit baked in parts (bake --only MODEL:SOLUTIONS) as one whole-model partial in `dir`: the
// model planned again, then every solution in bake order through the bake's own output.
Part assemble(const std::vector<Part>& parts, const fs::path& dir, const MergeOptions& opt, const RunContext& ctx) {
  const Part& first = parts.front();
  const nlohmann::json& u = first.unit();
  const std::string name = u["name"];
  const Scene scene = scene_of(first, opt);
  PlanOverrides ov = plan_overrides_from_json(u.at("plan_overrides"));
  ov.only = name;
  const BakePlan plan = make_plan(scene, ov, ctx);
  const ModelPlan& mp = plan.models.at(0);
  const std::string backend = first.manifest["backend"].value("name", "");
  const std::string hash = unit_hash(plan, mp, backend);
  if (hash != u.at("model_hash"))
    refuse(first.dir, "model '" + name + "' planned again has the inputs hash " + hash + ", not the parts' " +
                          u["model_hash"].get<std::string>() + " (its density source changed since?)",
           "/unit/model_hash");

  class Forward final : public BakeObserver {
   public:
    explicit Forward(BakeOutput& out) : out_(out) {}
    void solution_done(const ModelPlan& model, SolutionResult& r) override { out_.add(model, r); }

   private:
    BakeOutput& out_;
  };
  BakeOutput out(plan, dir,
                 {opt.command_line, backend, first.manifest["backend"].value("description", ""), nullptr,
                  unit_record(plan, mp, backend)});
  Forward forward(out);
  AmbientSum ambient(mp);
  double total_seconds = 0, peak = 0;
  for (const Part& p : parts) {
    total_seconds += p.manifest.value("total_seconds", 0.0);
    peak = std::max(peak, p.manifest["models"][0].value("peak_memory_bytes", 0.0));
  }
  out.set_peak_bytes(mp, static_cast<std::size_t>(peak));
  const bool moments = std::any_of(parts.begin(), parts.end(), [](const Part& p) { return p.unit().contains("flux"); });
  std::optional<SolutionResult> held_b00;
  for (const SolutionPlan& sp : mp.solutions) {  // bake order: index order, a summed B00 last
    if (sp.derived) continue;
    ctx.check_cancelled();
    const auto has = [&](const Part& p) {
      const nlohmann::json& s = p.unit()["solutions"];
      return std::find(s.begin(), s.end(), sp.index) != s.end();
    };
    const Part& p = *std::find_if(parts.begin(), parts.end(), has);  // coverage checked by the caller
    try {
      const nlohmann::json& rows = p.manifest["models"][0]["solutions"];
      const auto row = std::find_if(rows.begin(), rows.end(), [&](const nlohmann::json& r) { return r.at("index") == sp.index; });
      if (row == rows.end()) refuse(p.dir, "its manifest has no row for " + sp.grid_name, "/models/0/solutions");
      SolutionResult r = solution_from_row(*row, sp);
      const std::string file = p.unit().at("totals").at(sp.grid_name);
      const fs::path path = manifest_file(p.dir, file, "/unit/totals/" + sp.grid_name);
      if (file_checksum(path) != p.unit()["files"].at(file).at("checksum"))
        refuse(p.dir, file + " does not match its checksum (changed or damaged after the bake)");
      r.totals = read_raw_totals(path, mp.lattice.dims.count());
      const nlohmann::json flux_files = p.unit().value("flux", nlohmann::json::object());
      if (flux_files.contains(sp.grid_name)) {
        const std::string flux_file = flux_files.at(sp.grid_name);
        const fs::path flux_path = manifest_file(p.dir, flux_file, "/unit/flux/" + sp.grid_name);
        if (file_checksum(flux_path) != p.unit()["files"].at(flux_file).at("checksum"))
          refuse(p.dir, flux_file + " does not match its checksum (changed or damaged after the bake)");
        r.flux = read_raw_flux(flux_path, mp.lattice.dims.count());
      }
      ambient.add(r);
      // As bake_model does: a B00 solved from a source comes last, with the directional flux summed.
      if (sp.index == 0 && mp.model.first_collision_on() && moments)
        held_b00 = std::move(r);
      else
        out.add(mp, r);
    } catch (const nlohmann::json::exception& e) {
      refuse(p.dir, std::string("damaged: its manifest lacks what a bake writes: ") + e.what());
    }
  }
  if (held_b00) {
    if (held_b00->flux[0][0].empty()) ambient.fill_flux(*held_b00);
    out.add(mp, *held_b00);
  }
  ambient.finish(forward);
  out.finish_model(mp);
  spdlog::info("unit '{}': assembled from {} part(s) into its whole-model output", name, parts.size());
  return {dir, out.commit(total_seconds), true};
}

std::set<int> solution_set(const Part& p) { return p.unit()["solutions"].get<std::set<int>>(); }

// Removes the folder of assembled units however the merge ends.
struct RemoveOnExit {
  fs::path dir;
  ~RemoveOnExit() {
    std::error_code ec;
    if (!dir.empty()) fs::remove_all(dir, ec);
  }
};

}  // namespace

nlohmann::json merge_parts(const std::vector<fs::path>& parts, const fs::path& target, const MergeOptions& opt,
                           const RunContext& ctx) {
  if (parts.empty()) throw_invalid("no partial outputs to merge; give one folder per unit (lblight bake --only)");
  RunPaths paths;
  for (const fs::path& dir : parts) paths.input(dir, "part");
  if (!opt.scene_file.empty()) paths.input(opt.scene_file, "--scene");
  paths.output_folder(target, "-o").check();
  StagedDirectory::check_target(target, OutputKind::Bake);
  std::map<std::string, std::vector<Part>> by_unit;
  std::vector<std::string> units = opt.units;
  std::string reference_hash = opt.scene_hash, reference_words;
  if (!opt.scene_hash.empty())
    reference_words = "scene '" + opt.scene_name + "' (" + opt.scene_file + ", " + opt.scene_hash + ") given by --scene";
  std::optional<Part> first;
  for (const fs::path& dir : parts) {
    ctx.check_cancelled();
    // Which unit it claims to be, then everything checked against it (sizes here, checksums
    // while copying below).
    const PartCheck c = check_part(dir, "", "", false);
    if (c.state == PartState::Absent) refuse(dir, "no partial output there (missing or empty folder)");
    if (c.state != PartState::Done) refuse(dir, c.why);
    const Part part{dir, c.manifest};
    const nlohmann::json& m = part.manifest;
    const std::string name = part.unit()["name"];
    const std::string hash = m.at("scene").value("hash", "");
    if (reference_hash.empty()) {
      reference_hash = hash;
      reference_words = scene_words(m) + " of part " + dir.string();
    }
    if (hash != reference_hash)
      refuse(dir, "it is a bake of " + scene_words(m) + ", not of " + reference_words + " (a foreign partial)",
             "/scene/hash");
    if (units.empty()) units = part.unit()["units"].get<std::vector<std::string>>();
    if (part.unit()["units"] != nlohmann::json(units))
      refuse(dir, "its scene has the units " + part.unit()["units"].dump() + ", not " + nlohmann::json(units).dump(),
             "/unit/units");
    if (std::find(units.begin(), units.end(), name) == units.end())
      refuse(dir, "unit '" + name + "' is not a unit of the scene (" + join(units) + ")", "/unit/name");
    if (first)
      for (const std::string& field : kSharedFields) {
        const nlohmann::json::json_pointer p(field);
        const nlohmann::json a = first->manifest.contains(p) ? first->manifest[p] : nlohmann::json();
        const nlohmann::json b = m.contains(p) ? m[p] : nlohmann::json();
        if (a != b)
          refuse(dir, "its " + field + " is " + b.dump() + " but " + a.dump() + " in part " + first->dir.string() +
                          " (parts must come from the same lblight, backend and settings)",
                 field);
      }
    // A unit again: only as another share of a unit baked in parts, of the same plan.
    for (const Part& other : by_unit[name]) {
      if (!part.split() || !other.split())
        refuse(dir, "unit '" + name + "' is also given as " + other.dir.string() + "; give each unit once",
               "/unit/name");
      for (const char* key : {"model_hash", "model_solutions", "plan_overrides"})
        if (part.unit().value(key, nlohmann::json()) != other.unit().value(key, nlohmann::json()))
          refuse(dir, "its unit." + std::string(key) + " differs from part " + other.dir.string() +
                          "'s (shares of one unit must come from one plan)",
                 "/unit/" + std::string(key));
      std::vector<int> both;
      const std::set<int> a = solution_set(part), b = solution_set(other);
      std::set_intersection(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(both));
      if (!both.empty())
        refuse(dir, "its solutions " + nlohmann::json(both).dump() + " of unit '" + name + "' are also in part " +
                        other.dir.string() + "; give each solution once",
               "/unit/solutions");
    }
    by_unit[name].push_back(part);
    if (!first) first = part;
  }
  std::vector<std::string> missing;
  for (const std::string& u : units)
    if (by_unit[u].empty()) missing.push_back(u);
  if (!missing.empty())
    throw_invalid("missing unit(s) " + join(missing) + " of " + reference_words + ": a merge needs every unit (" +
                      join(units) + "); bake them with lblight bake --only UNIT, or lblight submit --resume");

  // Units baked in parts: every solution there, then assembled into one whole-model partial each.
  RemoveOnExit assembled{target.string() + ".assembling"};
  for (const std::string& u : units) {
    std::vector<Part>& shares = by_unit[u];
    if (!shares.front().split()) continue;
    std::set<int> have, want = shares.front().unit().at("model_solutions").get<std::set<int>>();
    for (const Part& p : shares)
      for (int i : solution_set(p)) have.insert(i);
    std::vector<int> lacking;
    std::set_difference(want.begin(), want.end(), have.begin(), have.end(), std::back_inserter(lacking));
    if (!lacking.empty())
      throw_invalid("unit '" + u + "' was baked in parts, and no part holds its solution(s) " +
                    nlohmann::json(lacking).dump() + "; bake them with lblight bake --only " + u + ":<solutions>");
    shares = {assemble(shares, assembled.dir / u, opt, ctx)};
  }

  StagedDirectory dir(target, OutputKind::Bake);
  nlohmann::json merged = first->manifest;
  merged.erase("unit");
  merged.erase("forest");
  merged["models"] = nlohmann::json::array();
  double total_seconds = 0;
  std::vector<std::string> descriptions;
  for (const std::string& u : units) {
    const Part& p = by_unit[u].front();
    const nlohmann::json& m = p.manifest;
    for (const auto& [file, pointer] : named_files(m)) {
      ctx.check_cancelled();
      const fs::path from = p.dir / file;
      const std::string expected = p.unit()["files"][file]["checksum"];
      std::string got;
      if (opt.move_files || p.owned) {
        got = file_checksum(from);
        if (got == expected) {
          std::error_code ec;
          fs::rename(from, dir.path(file), ec);
          if (ec) got = hash_and_copy(from, dir.path(file));
        }
      } else {
        got = hash_and_copy(from, dir.path(file));
      }
      if (got != expected)
        refuse(p.dir, file + " does not match its checksum (" + got + ", " + expected +
                          " written): changed or damaged after the bake");
    }
    merged["models"].push_back(m["models"][0]);
    total_seconds += m.value("total_seconds", 0.0);
    const std::string d = m["backend"].value("description", "");
    if (std::find(descriptions.begin(), descriptions.end(), d) == descriptions.end()) descriptions.push_back(d);
    if (m.contains("forest")) {
      if (merged.contains("forest") && merged["forest"] != m["forest"])
        refuse(p.dir, "its forest (instances, cell size) differs from the other parts'", "/forest");
      merged["forest"] = m["forest"];
    }
    spdlog::info("unit '{}': {} file(s) from {}", u, named_files(m).size(), p.dir.string());
  }
  merged["created"] = utc_timestamp();
  merged["command"] = opt.command_line;
  merged["total_seconds"] = total_seconds;
  merged["backend"]["description"] = join(descriptions, "; ");
  ctx.check_cancelled();
  write_file_atomically(dir.path("manifest.json"), merged.dump(2) + "\n");
  dir.commit();
  return merged;
}

const std::vector<std::string>& run_record_fields() {
  static const std::vector<std::string> fields = {
      "/created",
      "/command",
      "/total_seconds",
      "/backend/description",
      "/models/*/peak_memory_bytes",
      "/models/*/solutions/*/seconds",
      "/models/*/solutions/*/residual_history/*/1",
      "/models/*/solutions/*/compression/encode_seconds",
  };
  return fields;
}

nlohmann::json without_run_record(const nlohmann::json& manifest) {
  nlohmann::json m = manifest;
  if (m.is_object()) m.erase("unit");
  for (const std::string& field : run_record_fields()) {
    std::vector<std::string> parts;
    for (std::size_t at = 1; at <= field.size();) {
      const std::size_t end = std::min(field.find('/', at), field.size());
      parts.push_back(field.substr(at, end - at));
      at = end + 1;
    }
    drop(m, parts, 0);
  }
  return m;
}

}  // namespace lblight
