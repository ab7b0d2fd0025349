// Turns bake results into files: one <model>.vdb per model (float `density`, float `brown` when
// the model has wood, Vec3f B00..B18 or `light`) and manifest.json, all inside a staged
// directory that appears in place only when everything is written.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lblight/backend/backend.h"
#include "lblight/io/output_dir.h"
#include "lblight/solve/bake.h"

namespace lblight {

struct BakeRunInfo {
  std::string command_line;
  std::string backend_name, backend_description;
  Precision precision = Precision::Float32;
};

class BakeOutput {
 public:
  BakeOutput(const BakePlan& plan, const std::filesystem::path& target, BakeRunInfo info);

  void add(const ModelPlan& model, SolutionResult& result);  // takes the totals
  void set_peak_bytes(const ModelPlan& model, std::size_t bytes);
  void finish_model(const ModelPlan& model);                 // writes <model>.vdb
  // Writes manifest.json and moves the directory into place; returns the manifest.
  nlohmann::json commit(double total_seconds);

  const std::filesystem::path& target() const { return dir_.target(); }
  // Per solution rows for the summary table, in bake order.
  const nlohmann::json& models() const { return models_; }

 private:
  const BakePlan& plan_;
  StagedDirectory dir_;
  BakeRunInfo info_;
  std::vector<SolutionResult> pending_;
  std::size_t peak_bytes_ = 0;
  nlohmann::json models_ = nlohmann::json::array();
};

// Manifest pieces shared with `validate --json` and `inspect`.
nlohmann::json material_json(const Material& m);
nlohmann::json lattice_json(const ModelPlan& model);
nlohmann::json savings_json(const ModelPlan& model);  // what the plan leaves out
std::array<double, 3> lattice_origin_world(const ModelPlan& model);

}  // namespace lblight
