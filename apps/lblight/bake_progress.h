// The progress a bake shows (bake, simulate --light): one line per solution on stderr, a heartbeat
// every few seconds on long ones, and the rows of the summary table printed at the end.
#pragma once

#include <chrono>
#include <string>
#include <vector>

#include "lblight/solve/bake.h"

namespace lblight::cli {

class ProgressLog final : public BakeObserver {
 public:
  // total: the solutions of the whole bake, numbered 1..total; 0 numbers each model's own (the
  // frames of a gas sequence, planned one at a time).
  explicit ProgressLog(std::size_t total) : total_(total), per_model_(total == 0) {}

  void model_started(const ModelPlan& mp, const Backend& backend, std::size_t bytes, StateLayout layout) override;
  void progress(const BakeProgress& ev) override;
  void solution_done(const ModelPlan& mp, SolutionResult& r) override;

  std::size_t done() const { return rows_.size(); }  // solutions finished so far, all models
  // model, solution, direction, iterations, seconds, error estimate: in model and index order.
  std::vector<std::vector<std::string>> rows() const;

 private:
  std::size_t total_, done_ = 0;
  bool per_model_;
  std::chrono::steady_clock::time_point last_beat_;
  struct Row {
    std::size_t model;
    int index;
    std::vector<std::string> cells;
  };
  std::vector<std::string> models_;  // by name: a gas sequence's frame plans may share an address
  std::vector<Row> rows_;
};

}  // namespace lblight::cli
