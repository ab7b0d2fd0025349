// A bake split into work units (docs/scale-out.md): one per lattice of the plan (each scene model,
// the coarse forest grid "forest" and each "forest.alone.<model>"). A unit baked on its own
// (`bake --only`) writes a partial output: an ordinary bake output of that one lattice whose
// manifest also holds a "unit" object (its name, the content hash of its inputs, every unit of the
// scene and its files' checksums). `merge` combines the partials of every unit into exactly the
// output of a one-machine bake; `--resume` skips units whose partial is finished.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lblight/core/run_context.h"
#include "lblight/solve/plan.h"

namespace lblight {

// The content hash of a unit's inputs, "fnv1a64:<hex>": lblight's version and manifest format,
// the scene's hash (its JSON content), the unit's lattice (density and material of every node,
// box, transform), materials, solutions with their boundary values, step policy, precision and
// the backend's name (backends agree to rounding, not bit for bit). Equal hashes: the unit's
// output would be the same.
std::string unit_hash(const BakePlan& plan, const ModelPlan& model, const std::string& backend_name);

// What `bake --only` names: a lattice, and optionally some of its solutions ("tree:1-6", indices
// as --solutions takes them). Error(InvalidInput) naming --only otherwise.
struct UnitSpec {
  std::string name;
  std::vector<int> solutions;  // empty: the whole lattice
};
UnitSpec parse_unit(const std::string& text);

// The "unit" object of a partial output's manifest, without "files" (BakeOutput adds them). A unit
// of some solutions also records them, the whole model's hash and solved solutions, and the plan
// overrides (`overrides`) a merge needs to plan the model again when it assembles it.
nlohmann::json unit_record(const BakePlan& plan, const ModelPlan& model, const std::string& backend_name,
                           const PlanOverrides& overrides = {}, const std::vector<int>& solutions = {});

// A plan of the one lattice `index` of `full` (moved out of it) with what its partial's manifest
// needs: the forest object only where a one-lattice plan (make_plan with `only`) has it.
BakePlan unit_plan(BakePlan& full, std::size_t index);

// The plan overrides a unit of some solutions records ("plan_overrides"), back.
PlanOverrides plan_overrides_from_json(const nlohmann::json& j);

// "fnv1a64:<hex>" of a file's bytes. Error(Io) when it cannot be read.
std::string file_checksum(const std::filesystem::path& file);
// {"<file>": {"bytes": n, "checksum": "..."}} for the files a manifest's models name in `dir`.
nlohmann::json file_checksums(const std::filesystem::path& dir, const nlohmann::json& manifest);

// What a folder holds for a unit.
enum class PartState {
  Absent,  // nothing there (or an empty folder)
  Done,    // a finished partial of that unit with the expected inputs hash
  Other,   // something else (`why`): damaged, another unit, other inputs, not a partial
};
struct PartCheck {
  PartState state = PartState::Absent;
  std::string why;
  nlohmann::json manifest;  // when it could be read
};
// Checks `dir` as the partial of unit `name` (empty: any unit) with inputs hash `hash` (empty: any). Files are
// checked by size, and by checksum when `verify_checksums` (which reads them whole).
PartCheck check_part(const std::filesystem::path& dir, const std::string& name, const std::string& hash,
                     bool verify_checksums);

struct MergeOptions {
  std::string command_line;
  // The scene every part must belong to (merge --scene): its hash and its units. Empty: the
  // first part's.
  std::string scene_hash, scene_name, scene_file;
  std::vector<std::string> units;
  bool move_files = false;  // rename the parts' files instead of copying (a bake --resume's own parts)
};

// Combines partial outputs into `target` (staged: complete or untouched). Every part must be a
// finished partial of the same scene, lblight version, backend and precision, every unit given
// exactly once (or, for a unit split by solutions, every solution exactly once), and every file
// must match its checksum; otherwise Error(InvalidInput) naming the part (a damaged or foreign
// partial is never merged). A split unit is assembled first: its model planned again (the scene
// from --scene or the parts' manifest; its hash must be the parts'), the parts' totals fed in bake
// order through the bake's own output (BakeOutput, B00 summed by AmbientSum). The manifest equals a
// one-machine bake's except its run record (run_record_fields): created and command are the
// merge's, total_seconds the sum of the units', backend.description the units' (distinct ones
// joined by "; "). Returns it.
nlohmann::json merge_parts(const std::vector<std::filesystem::path>& parts, const std::filesystem::path& target,
                           const MergeOptions& options, const RunContext& ctx = {});

// The manifest fields that record how and when a bake ran rather than what it computed, as JSON
// pointers ("*": every array element): they differ between two runs of the same bake.
const std::vector<std::string>& run_record_fields();
// `manifest` without them (and without a partial's "unit"): two bakes of the same inputs on the same
// backend give equal results.
nlohmann::json without_run_record(const nlohmann::json& manifest);

}  // namespace lblight
