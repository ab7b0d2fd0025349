#include "apps/lblight/bake_progress.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "apps/lblight/cli_support.h"

namespace lblight::cli {

void ProgressLog::model_started(const ModelPlan& mp, const Backend& backend, std::size_t bytes,
                                StateLayout layout) {
  if (per_model_) {
    total_ = mp.solutions.size();
    done_ = 0;
  }
  const Dims& d = mp.lattice.dims;
  const bool in_place = layout == StateLayout::InPlace;
  spdlog::info("model '{}': {}x{}x{} lattice, {} solution(s) x {} distinct channel(s) on {} ({} for the lattice{})",
               mp.spec->name, d.nx, d.ny, d.nz, mp.solutions.size(), mp.channels.size(), backend.name(),
               format_bytes(static_cast<double>(bytes)), in_place ? ", state updated in place" : "");
  if (!mp.steps.method_note.empty()) spdlog::info("model '{}': {}", mp.spec->name, mp.steps.method_note);
  last_beat_ = std::chrono::steady_clock::now();
}

void ProgressLog::progress(const BakeProgress& ev) {
  const auto now = std::chrono::steady_clock::now();
  if (std::chrono::duration<double>(now - last_beat_).count() < 3.0) return;
  last_beat_ = now;
  std::string names;
  for (const SolutionPlan* s : ev.batch) names += (names.empty() ? "" : ",") + s->grid_name;
  spdlog::info("  [{}] {}: step {}/{}{}, est. error {}, {} s", ev.model->spec->name, names, ev.step,
               ev.planned_steps, ev.model->steps.mode == IterationMode::Auto ? " max" : "",
               format_error(ev.error_estimate), format_seconds(ev.seconds));
}

void ProgressLog::solution_done(const ModelPlan& mp, SolutionResult& r) {
  ++done_;
  const bool auto_mode = mp.steps.mode == IterationMode::Auto;
  spdlog::info("[{}/{}] {} {} {}: {} steps{}, {} s, est. error {}{}", done_, total_, mp.spec->name, r.plan.grid_name,
               format_direction(r.plan.direction), r.iterations, r.warm_start ? " (warm start)" : "",
               format_seconds(r.seconds), format_error(r.error_estimate),
               auto_mode ? (r.converged ? " (converged)" : " (NOT converged: raise max_iterations)") : "");
  if (auto_mode && !r.converged)
    spdlog::warn("{} {}: stopped at max_iterations {} with est. error {} above tolerance {}", mp.spec->name,
                 r.plan.grid_name, r.iterations, format_error(r.error_estimate), mp.steps.tolerance);
  // Summary rows in model and index order (a B00 summed from the others arrives last).
  if (models_.empty() || models_.back() != mp.spec->name) models_.push_back(mp.spec->name);
  rows_.push_back({models_.size(), r.plan.index,
                   {mp.spec->name, r.plan.grid_name, format_direction(r.plan.direction),
                    r.plan.derived ? "sum" : std::to_string(r.iterations), format_seconds(r.seconds),
                    format_error(r.error_estimate)}});
}

std::vector<std::vector<std::string>> ProgressLog::rows() const {
  auto sorted = rows_;
  std::stable_sort(sorted.begin(), sorted.end(), [](const Row& a, const Row& b) {
    return a.model != b.model ? a.model < b.model : a.index < b.index;
  });
  std::vector<std::vector<std::string>> out;
  for (const Row& r : sorted) out.push_back(r.cells);
  return out;
}

}  // namespace lblight::cli
