#include "lblight/pipeline/manifest.h"

#include "lblight/core/error.h"
#include "lblight/core/input_file.h"
#include "lblight/scene/json_reader.h"

namespace fs = std::filesystem;

namespace lblight {
namespace {

class Checker {
 public:
  explicit Checker(const std::string& file) : file_(file) {}
  [[noreturn]] void fail(const std::string& pointer, const std::string& what) const {
    throw_invalid("manifest.json is not an lblight bake manifest: " + what, {file_, pointer, {}});
  }
  const nlohmann::json& member(const nlohmann::json& obj, const std::string& pointer, const char* key) const {
    if (!obj.contains(key)) fail(pointer + "/" + key, "missing");
    return obj.at(key);
  }
  void string_or_null(const nlohmann::json& v, const std::string& pointer) const {
    if (!v.is_string() && !v.is_null()) fail(pointer, "must be a file name or null, not " + std::string(v.type_name()));
  }
  void ints(const nlohmann::json& v, const std::string& pointer, std::size_t n) const {
    if (!v.is_array() || v.size() != n) fail(pointer, "must be an array of " + std::to_string(n) + " integers");
    for (const auto& e : v)
      if (!e.is_number_integer()) fail(pointer, "must be an array of " + std::to_string(n) + " integers");
  }

 private:
  std::string file_;
};

}  // namespace

nlohmann::json parse_manifest(const std::string& text, const std::string& file) {
  const Checker c(file);
  // depth-checked before the document is built: a million nested arrays would overflow the stack
  nlohmann::json m = JsonReader::parse_strict(text, file);
  if (!m.is_object()) c.fail("", "the top level must be an object");
  const nlohmann::json& models = c.member(m, "", "models");
  if (!models.is_array()) c.fail("/models", "must be an array");
  for (std::size_t i = 0; i < models.size(); ++i) {
    const std::string at = "/models/" + std::to_string(i);
    const nlohmann::json& model = models[i];
    if (!model.is_object()) c.fail(at, "must be an object");
    if (!c.member(model, at, "name").is_string()) c.fail(at + "/name", "must be a string");
    c.string_or_null(c.member(model, at, "file"), at + "/file");
    if (model.contains("lbh_file")) c.string_or_null(model["lbh_file"], at + "/lbh_file");
    const nlohmann::json& lattice = c.member(model, at, "lattice");
    if (!lattice.is_object()) c.fail(at + "/lattice", "must be an object");
    c.ints(c.member(lattice, at + "/lattice", "dims"), at + "/lattice/dims", 3);
    c.ints(c.member(lattice, at + "/lattice", "index_min"), at + "/lattice/index_min", 3);
    const nlohmann::json& solutions = c.member(model, at, "solutions");
    if (!solutions.is_array()) c.fail(at + "/solutions", "must be an array");
    for (std::size_t k = 0; k < solutions.size(); ++k) {
      const std::string sat = at + "/solutions/" + std::to_string(k);
      const nlohmann::json& s = solutions[k];
      if (!s.is_object()) c.fail(sat, "must be an object");
      if (!c.member(s, sat, "grid").is_string()) c.fail(sat + "/grid", "must be a string");
      if (s.contains("direction")) c.ints(s["direction"], sat + "/direction", 3);
      if (s.contains("iterations") && !s["iterations"].is_number_integer())
        c.fail(sat + "/iterations", "must be an integer");
      if (s.contains("seconds") && !s["seconds"].is_number()) c.fail(sat + "/seconds", "must be a number");
      if (s.contains("error_estimate") && !s["error_estimate"].is_number() && !s["error_estimate"].is_null())
        c.fail(sat + "/error_estimate", "must be a number or null");
    }
  }
  return m;
}

nlohmann::json read_manifest(const fs::path& dir) {
  const fs::path file = dir / "manifest.json";
  return parse_manifest(read_input_file(file, "manifest", kMaxManifestBytes), file.string());
}

fs::path manifest_file(const fs::path& dir, const std::string& name, const std::string& json_path) {
  const Location where{(dir / "manifest.json").string(), json_path, {}};
  const fs::path p(name);
  if (name.empty() || name == "." || name == ".." || p.is_absolute() || p.has_parent_path() ||
      name.find('\0') != std::string::npos)
    throw_invalid("manifest names the file '" + name + "'; allowed: a file name inside the output folder", where);
  std::error_code ec;
  const fs::path base = fs::weakly_canonical(dir, ec);
  const fs::path full = fs::weakly_canonical(dir / p, ec);
  if (ec || full.parent_path() != base)
    throw_invalid("manifest names the file '" + name + "', which leads outside the output folder " + dir.string() +
                      "; allowed: a file inside it",
                  where);
  return dir / p;
}

bool solved_with_delta_m(const nlohmann::json& m) {
  // "calibrated", or "calibrated (no ...; with ...)" when switches differ from the defaults
  // (LbModel::name()): first_collision on made the default scene's name the second kind.
  if (!m.is_object() || m.value("lb_model", "").rfind("calibrated", 0) != 0) return false;
  const nlohmann::json switches = m.value("lb_calibration", nlohmann::json::object());
  return !switches.is_object() || switches.value("delta_m", true);
}

bool bake_solved_with_delta_m(const fs::path& path) {
  std::error_code ec;
  const bool folder = fs::is_directory(path, ec);
  const fs::path dir = folder ? path : path.parent_path().empty() ? fs::path(".") : path.parent_path();
  if (!fs::is_regular_file(dir / "manifest.json", ec)) return false;
  const nlohmann::json m = read_manifest(dir);
  for (const nlohmann::json& entry : m["models"])
    if (folder || entry["file"] == path.filename().string()) return solved_with_delta_m(entry);
  return false;
}

}  // namespace lblight
