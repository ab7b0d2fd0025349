#include "lblight/solve/bake.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "lblight/core/error.h"

namespace lblight {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

std::string gib(std::size_t bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f GiB", static_cast<double>(bytes) / (1024.0 * 1024.0 * 1024.0));
  return buf;
}

// How many systems one batch holds: whole solutions where possible, within device memory.
int batch_capacity(const ModelPlan& mp, const Backend& backend, const BakeOptions& opt) {
  const Dims& d = mp.lattice.dims;
  const std::size_t per_system = backend.bytes_per_system(d, opt.precision);
  const std::size_t fixed = backend.bytes_per_lattice(d);
  const std::size_t avail = backend.available_bytes();
  const int channels = static_cast<int>(mp.channels.size());
  const int total = static_cast<int>(mp.systems());
  int want = opt.max_systems > 0 ? opt.max_systems : backend.preferred_batch(d, opt.precision, total);
  want = std::max(1, std::min(want, total));
  // whole solutions per batch: a multiple of the channel count where possible
  if (want > channels) want -= want % channels;
  if (avail > 0) {
    // keep a tenth of the free memory for everything else
    const double usable = 0.9 * static_cast<double>(avail) - static_cast<double>(fixed);
    const int fit = usable > 0 ? static_cast<int>(usable / static_cast<double>(per_system)) : 0;
    if (fit < 1)
      throw Error(ErrorCategory::Unavailable,
                  "model '" + mp.spec->name + "': a " + std::to_string(d.nx) + "x" + std::to_string(d.ny) + "x" +
                      std::to_string(d.nz) + " lattice needs " + gib(fixed + per_system) + " on the " +
                      backend.name() + " backend but only " + gib(avail) +
                      " is available; lower the resolution or use a machine with more memory");
    want = std::min(want, fit);
  }
  return want;
}

struct SystemRef {
  int solution;  // index into mp.solutions
  int channel;   // index into mp.channels
};

}  // namespace

void bake_model(const ModelPlan& mp, const Backend& backend, const BakeOptions& opt, BakeObserver& observer) {
  const int capacity = batch_capacity(mp, backend, opt);
  SolverOptions so;
  so.precision = opt.precision;
  so.max_systems = capacity;
  auto solver = backend.create(mp.lattice, mp.channels, so);
  observer.model_started(mp, backend, solver->bytes_in_use());

  std::vector<SystemRef> queue;
  for (int s = 0; s < static_cast<int>(mp.solutions.size()); ++s)
    for (int c = 0; c < static_cast<int>(mp.channels.size()); ++c) queue.push_back({s, c});

  // Per solution, what its channels have produced so far (channels may run in separate batches
  // when memory is short).
  struct Pending {
    std::vector<std::vector<float>> per_channel;
    int channels_done = 0, iterations = 0;
    double seconds = 0, error_estimate = 0, error_estimate_max = 0;
    bool converged = true;
    std::vector<CheckPoint> history;
  };
  std::vector<Pending> pending(mp.solutions.size());
  for (Pending& p : pending) p.per_channel.resize(mp.channels.size());

  const StepPolicy& pol = mp.steps;
  const double round_off = ConvergenceMonitor::round_off_for(opt.precision);
  const std::size_t count = mp.lattice.dims.count();

  for (std::size_t start = 0; start < queue.size();) {
    // Fill the batch, but never split a solution's channels across two batches when they fit.
    std::size_t end = std::min(queue.size(), start + static_cast<std::size_t>(capacity));
    if (end < queue.size() && static_cast<int>(mp.channels.size()) <= capacity)
      while (end > start + 1 && queue[end].solution == queue[end - 1].solution) --end;
    std::vector<SystemSpec> batch;
    std::vector<const SolutionPlan*> batch_solutions;
    for (std::size_t q = start; q < end; ++q) {
      const SolutionPlan* sp = &mp.solutions[static_cast<std::size_t>(queue[q].solution)];
      batch.push_back({queue[q].channel, sp->boundary});
      if (batch_solutions.empty() || batch_solutions.back() != sp) batch_solutions.push_back(sp);
    }

    const auto t0 = Clock::now();
    solver->reset(batch);
    std::vector<ConvergenceMonitor> monitors(batch.size(), ConvergenceMonitor(round_off));
    std::vector<Residual> residuals;
    std::vector<CheckPoint> worst_history;
    int step = 0;
    bool converged = false;
    const bool fixed = pol.mode != IterationMode::Auto;
    const int total = fixed ? pol.fixed_steps : pol.max_steps;
    double worst = ConvergenceMonitor::kUnknown;
    while (step < total) {
      // Fixed runs put their checks on the last steps (N, N-K, N-2K, ...), so the final error
      // estimate compares equal intervals.
      int chunk = pol.check_interval;
      if (fixed && step == 0 && total % pol.check_interval != 0) chunk = total % pol.check_interval;
      chunk = std::min(chunk, total - step);
      solver->step(chunk);
      step += chunk;
      solver->measure(residuals);
      const double secs = seconds_since(t0);
      worst = 0;
      CheckPoint worst_point;
      for (std::size_t s = 0; s < batch.size(); ++s) {
        monitors[s].record(step, chunk, secs, residuals[s]);
        if (!residuals[s].finite)
          throw Error(ErrorCategory::Internal,
                      "model '" + mp.spec->name + "': the iteration produced NaN or Inf at step " +
                          std::to_string(step) + "; this should have been rejected by validation, please report it");
        const CheckPoint& cp = monitors[s].history().back();
        if (s == 0 || cp.error_estimate > worst_point.error_estimate || std::isnan(cp.error_estimate)) worst_point = cp;
        worst = std::max(worst, monitors[s].error_estimate());
      }
      worst_history.push_back(worst_point);
      BakeProgress ev{&mp, batch_solutions, step, total, worst, secs};
      observer.progress(ev);
      if (opt.cancel && opt.cancel->load()) throw Error(ErrorCategory::Cancelled, "interrupted");
      if (!fixed && step >= pol.min_steps && worst < pol.tolerance) {
        converged = true;
        break;
      }
    }
    const double batch_seconds = seconds_since(t0);

    // Collect each system's totals; a solution is done once all its channels are.
    for (std::size_t s = 0; s < batch.size(); ++s) {
      const int sol = queue[start + s].solution;
      Pending& p = pending[static_cast<std::size_t>(sol)];
      auto& buf = p.per_channel[static_cast<std::size_t>(batch[s].channel)];
      buf.resize(count);
      solver->read_totals(static_cast<int>(s), buf.data());
      ++p.channels_done;
      p.iterations = std::max(p.iterations, step);
      p.seconds += batch_seconds / static_cast<double>(batch.size());
      p.error_estimate = std::max(p.error_estimate, monitors[s].error_estimate());
      p.error_estimate_max = std::max(p.error_estimate_max, monitors[s].error_estimate_max());
      p.converged = p.converged && converged;
      if (p.history.empty() || monitors[s].error_estimate() >= p.error_estimate) p.history = worst_history;
      if (p.channels_done < static_cast<int>(mp.channels.size())) continue;
      SolutionResult r;
      r.plan = mp.solutions[static_cast<std::size_t>(sol)];
      r.iterations = p.iterations;
      r.seconds = p.seconds;
      r.error_estimate = p.error_estimate;
      r.error_estimate_max = p.error_estimate_max;
      r.converged = !fixed && p.converged;
      r.history = std::move(p.history);
      for (int c = 0; c < kChannels; ++c) r.totals[c] = p.per_channel[static_cast<std::size_t>(mp.channel_of[c])];
      p = Pending{};
      observer.solution_done(mp, r);
    }
    start = end;
  }
}

}  // namespace lblight
