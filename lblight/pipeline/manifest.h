// Reading a bake's manifest.json back (compare, inspect, the check before an output is replaced):
// read bounded, its structure checked before any field is used, and the files it names confined
// to its own output folder (docs/output-format.md, docs/reliability.md).
#pragma once

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

namespace lblight {

// A manifest larger than this is not one lblight wrote (a bake of 1000 models writes ~10 MiB).
inline constexpr std::uint64_t kMaxManifestBytes = 64ull << 20;

// Parses manifest text and checks the fields readers use: "models" an array of objects, each with
// a string "name", "file" and "lbh_file" null or a file name, "lattice" with "dims" and
// "index_min" (3 integers each) and "solutions" an array of objects with a string "grid" (and, where
// present, "direction" 3 integers, "iterations" an integer, "seconds" a number, "error_estimate" a
// number or null). Error(InvalidInput) naming `file` and the JSON pointer of the first fault.
nlohmann::json parse_manifest(const std::string& text, const std::string& file);

// <dir>/manifest.json read (a regular file of at most kMaxManifestBytes) and parsed as above.
nlohmann::json read_manifest(const std::filesystem::path& dir);

// The file a manifest entry (`json_path`, e.g. /models/0/file) names, inside `dir`: a plain file
// name (no folder part, not "." or ".."), and, once resolved (symlinks followed), a path inside
// `dir` itself. Error(InvalidInput) naming the manifest and the entry otherwise: a manifest is
// input, and must not make lblight read /etc/passwd or /dev/zero.
std::filesystem::path manifest_file(const std::filesystem::path& dir, const std::string& name,
                                    const std::string& json_path);

// Whether the light of a model entry was solved with the calibrated model's delta-M scaling (its
// "lb_model" and "lb_calibration"): what a renderer of that light must know (docs/rendering.md).
bool solved_with_delta_m(const nlohmann::json& model_entry);
// The same for the bake `vdb` lies in (its manifest.json beside it, the entry naming it; for a
// forest bake any model's entry, as they share the scene's solver); false without a manifest.
bool bake_solved_with_delta_m(const std::filesystem::path& vdb_or_folder);

}  // namespace lblight
