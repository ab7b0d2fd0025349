// Turns bake results into files: one <model>.vdb per model (float `density`, float `brown` when
// the model has wood, Vec3f B00..B18 or `light`, and their `_se` for a reference), <model>.lbh when asked, and manifest.json, all
// inside a staged directory that appears in place only when everything is written. Each solution
// is converted, compressed and appended to the .vdb as it arrives (in arrival order), on a
// background thread when the solver does not use the host's cores, so output overlaps the solve.
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lblight/backend/backend.h"
#include "lblight/compress/lbh_writer.h"
#include "lblight/core/serial_worker.h"
#include "lblight/io/output_dir.h"
#include "lblight/io/vdb_stream_writer.h"
#include "lblight/solve/bake.h"

namespace lblight {

// What the manifest records about the run besides the plan (which holds the precision).
struct BakeRunInfo {
  std::string command_line;
  std::string backend_name, backend_description;
  // A Monte Carlo reference (lblight truth): its settings, recorded as the manifest's
  // "reference"; each solution then also gets a grid <name>_se with its standard error.
  nlohmann::json reference;
  // A work unit's partial output (docs/scale-out.md): its name, inputs hash and the scene's units,
  // recorded as the manifest's "unit" with the checksums of the files written. A unit of some of
  // a model's solutions ("solutions") also writes each one's totals as solved (unmasked floats,
  // write_raw_totals) to <model>.<grid>.totals, from which a merge assembles the whole model.
  nlohmann::json unit;
};

// What a caller adds to one model's output besides the bake's own (a gas frame's temperature,
// velocity and frame number): grids on the model's lattice frame, written after its density;
// members of the .vdb's file metadata; members of its manifest entry.
struct ModelExtras {
  struct Grid {
    std::string name;
    std::vector<float> scalar;              // a float grid, or (empty) ...
    std::array<std::vector<float>, 3> rgb;  // ... a Vec3f grid
    nlohmann::json metadata = nlohmann::json::object();
  };
  std::vector<Grid> grids;
  nlohmann::json file_metadata = nlohmann::json::object();
  nlohmann::json manifest = nlohmann::json::object();
};

class BakeOutput {
 public:
  // write_in_background: run the output work on a thread of its own (GPU backends). kind: what
  // the folder is (a lit gas sequence is a Simulation that also holds a manifest).
  BakeOutput(const BakePlan& plan, const std::filesystem::path& target, BakeRunInfo info,
             bool write_in_background = false, OutputKind kind = OutputKind::Bake);
  ~BakeOutput();

  // Before the model's first solution; kept until its finish_model.
  void set_extras(const ModelPlan& model, ModelExtras extras);
  void add(const ModelPlan& model, SolutionResult& result);  // takes the totals
  void set_peak_bytes(const ModelPlan& model, std::size_t bytes);
  void finish_model(const ModelPlan& model);                 // completes <model>.vdb and .lbh
  // Writes manifest.json and moves the directory into place; returns the manifest.
  nlohmann::json commit(double total_seconds);

  const std::filesystem::path& target() const { return dir_.target(); }
  // A file of the output, to write before commit (it appears with the rest).
  std::filesystem::path path(const std::string& name) const { return dir_.path(name); }
  // Per solution rows for the summary table, in bake order.
  const nlohmann::json& models() const { return models_; }

 private:
  void start_model(const ModelPlan& model, bool flux);  // flux: each solution has its 3 flux grids
  std::size_t solutions_expected(const ModelPlan& model) const;
  const ModelExtras* extras_for(const ModelPlan& model) const;
  int grids_per_solution() const { return info_.reference.is_null() ? 1 : 2; }

  const BakePlan& plan_;
  StagedDirectory dir_;
  BakeRunInfo info_;
  // Per model, while it is being baked. Declared before worker_: the worker stops first.
  const ModelPlan* model_ = nullptr;
  bool flux_grids_ = false;
  std::map<std::string, std::string> raw_flux_files_;  // a unit's <grid> -> <model>.<grid>.flux  // the model's .vdb holds <grid>_flux_r/_g/_b (SolutionResult::flux)
  const ModelPlan* extras_model_ = nullptr;  // the model extras_ belong to
  ModelExtras extras_;
  std::vector<SolutionResult> done_;   // manifest rows (totals handed to the worker)
  std::vector<LbhEncoded> encoded_;    // slot i: done_[i], filled by the worker
  std::vector<std::uint8_t> keep_;     // nodes whose light is written (empty: all of them)
  std::vector<float> medium_density_;  // the lattice's density without its ground layer
  std::vector<double> half_error_;     // slot i: done_[i]'s half rounding error, filled by the worker
  std::unique_ptr<VdbStreamWriter> vdb_;
  double output_seconds_ = 0;          // worker time spent on this model's output
  std::size_t peak_bytes_ = 0;
  std::size_t unit_solutions_ = 0;     // a unit of that many of a model's solutions (0: all)
  std::map<std::string, std::string> raw_files_;  // grid -> its .totals file
  nlohmann::json models_ = nlohmann::json::array();
  SerialWorker worker_;
};

// A solution's totals as a unit's .totals file: R, G, B, one float per lattice node each (native
// byte order: a merge reads them on the same cluster), and back. Error(Io) / Error(InvalidInput)
// naming the file when it cannot be written or read, or its size is not 3 x `nodes` floats.
void write_raw_totals(const std::filesystem::path& file, const std::array<std::vector<float>, 3>& totals);
std::array<std::vector<float>, 3> read_raw_totals(const std::filesystem::path& file, std::size_t nodes);
// A unit's flux as solved (SolutionResult::flux): <model>.<grid>.flux, 3 channels x 3 axes x nodes floats.
void write_raw_flux(const std::filesystem::path& file, const std::array<FluxField, 3>& flux);
std::array<FluxField, 3> read_raw_flux(const std::filesystem::path& file, std::size_t nodes);

// Manifest pieces shared with `validate --json` and `inspect`.
nlohmann::json material_json(const Material& m);
nlohmann::json lattice_json(const ModelPlan& model);
nlohmann::json savings_json(const ModelPlan& model);  // what the plan leaves out
// The manifest's "forest": cell size and the instance table (docs/forest.md).
nlohmann::json forest_json(const ForestPlan& forest);
std::array<double, 3> lattice_origin_world(const ModelPlan& model);

}  // namespace lblight
