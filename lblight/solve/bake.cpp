#include "lblight/solve/bake.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "lblight/core/error.h"
#include "lblight/solve/krylov.h"

namespace lblight {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

std::string gib(std::size_t bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f GiB", static_cast<double>(bytes) / (1024.0 * 1024.0 * 1024.0));
  return buf;
}

// How one batch ended.
struct BatchOutcome {
  int steps = 0;
  bool converged = false;
  std::vector<ConvergenceMonitor> monitors;
  // Per system, once its estimate has been below the tolerance (after min_steps): the smallest
  // estimate since (inf before). Further steps only bring the state closer to the fixed point, so
  // that estimate stays a bound while the rest of the batch goes on; without the latch, estimates
  // near the noise level of several systems would all have to dip below the tolerance at once.
  std::vector<double> latched, latched_max;
  std::vector<CheckPoint> worst_history;  // the worst system at every check
  int krylov_iterations = 0;
  double krylov_residual = 0;
};

class BatchRunner {
 public:
  BatchRunner(const ModelPlan& mp, LatticeSolver& solver, const BakeOptions& opt, BakeObserver& observer,
              std::vector<const SolutionPlan*> solutions, std::size_t systems)
      : mp_(mp), solver_(solver), opt_(opt), observer_(observer), solutions_(std::move(solutions)) {
    out_.monitors.assign(systems, ConvergenceMonitor(opt.precision, 1.0 - mp.steps.decay_hint));
    reset_latches();
    t0_ = Clock::now();
  }

  // Plain iteration x <- T(x) with checks every K steps (spec sec. 5).
  BatchOutcome plain() {
    const StepPolicy& pol = mp_.steps;
    const bool fixed = pol.mode != IterationMode::Auto;
    const int total = fixed ? pol.fixed_steps : pol.max_steps;
    while (out_.steps < total) {
      // Fixed runs put their checks on the last steps (N, N-K, N-2K, ...), so the final error
      // estimate compares equal intervals.
      int chunk = pol.check_interval;
      if (fixed && out_.steps == 0 && total % pol.check_interval != 0) chunk = total % pol.check_interval;
      chunk = std::min(chunk, total - out_.steps);
      if (check(chunk, total) && !fixed && out_.steps >= pol.min_steps) {
        out_.converged = true;
        break;
      }
    }
    return std::move(out_);
  }

  // BiCGStab rounds, each verified by plain checks with the same error estimate; a round that
  // does not verify is followed by one with a ten times tighter residual.
  BatchOutcome krylov() {
    const StepPolicy& pol = mp_.steps;
    double residual_tolerance = 0.1 * pol.tolerance;
    for (int round = 0; round < 4 && out_.steps < pol.max_steps; ++round) {
      KrylovProgress iterate;
      if (observer_.wants_iterates())
        iterate = [&](const KrylovResult& k) {
          observer_.inspect({&mp_, solutions_, out_.steps + k.steps, pol.max_steps, ConvergenceMonitor::kUnknown,
                             seconds_since(t0_), ConvergenceMonitor::kUnknown},
                            solver_, false);
        };
      const KrylovResult kr =
          bicgstab(*solver_.krylov_vectors(), residual_tolerance, pol.max_steps - out_.steps, opt_.cancel, iterate);
      out_.steps += kr.steps;
      out_.krylov_iterations += kr.iterations;
      out_.krylov_residual = kr.residual;
      // verification: a fresh monitor, a baseline measure, then plain checks
      out_.monitors.assign(out_.monitors.size(), ConvergenceMonitor(opt_.precision, 1.0 - pol.decay_hint));
      reset_latches();
      std::vector<Residual> ignore;
      solver_.measure(ignore);
      for (int c = 0; c < 6 && out_.steps < pol.max_steps; ++c)
        if (check(std::min(pol.check_interval, pol.max_steps - out_.steps), pol.max_steps)) {
          out_.converged = true;
          return std::move(out_);
        }
      residual_tolerance *= 0.1;
    }
    return std::move(out_);
  }

  double seconds() const { return seconds_since(t0_); }

 private:
  void reset_latches() {
    out_.latched.assign(out_.monitors.size(), ConvergenceMonitor::kUnknown);
    out_.latched_max.assign(out_.monitors.size(), ConvergenceMonitor::kUnknown);
  }

  // Runs `chunk` steps and a measure; true when every system's estimate has been below tolerance.
  bool check(int chunk, int planned) {
    solver_.step(chunk);
    out_.steps += chunk;
    solver_.measure(residuals_);
    const double secs = seconds_since(t0_);
    double worst = 0, worst_max = 0;
    bool all_latched = true;
    CheckPoint worst_point;
    for (std::size_t s = 0; s < out_.monitors.size(); ++s) {
      out_.monitors[s].record(out_.steps, chunk, secs, residuals_[s]);
      if (!residuals_[s].finite)
        throw Error(ErrorCategory::Internal,
                    "model '" + mp_.spec->name + "': the iteration produced NaN or Inf at step " +
                        std::to_string(out_.steps) +
                        "; this should have been rejected by validation, please report it");
      const CheckPoint& cp = out_.monitors[s].history().back();
      if (s == 0 || cp.error_estimate > worst_point.error_estimate || std::isnan(cp.error_estimate)) worst_point = cp;
      const double e = out_.monitors[s].error_estimate(), em = out_.monitors[s].error_estimate_max();
      if (out_.steps >= mp_.steps.min_steps && (e < mp_.steps.tolerance || std::isfinite(out_.latched[s]))) {
        out_.latched[s] = std::min(out_.latched[s], e);
        out_.latched_max[s] = std::min(out_.latched_max[s], em);
      }
      all_latched = all_latched && out_.latched[s] < mp_.steps.tolerance;
      worst = std::max(worst, std::min(e, out_.latched[s]));
      worst_max = std::max(worst_max, std::min(em, out_.latched_max[s]));
    }
    out_.worst_history.push_back(worst_point);
    const BakeProgress ev{&mp_, solutions_, out_.steps, planned, worst, secs, worst_max};
    observer_.progress(ev);
    observer_.inspect(ev, solver_, true);
    throw_if_cancelled(opt_.cancel);
    return all_latched;
  }

  const ModelPlan& mp_;
  LatticeSolver& solver_;
  const BakeOptions& opt_;
  BakeObserver& observer_;
  std::vector<const SolutionPlan*> solutions_;
  BatchOutcome out_;
  std::vector<Residual> residuals_;
  Clock::time_point t0_;
};

struct SystemRef {
  int solution;  // index into mp.solutions
  int channel;   // index into mp.channels
};

// B_0 assembled from the directional solutions as they finish (spec sec. 4). Interior nodes:
// the sum; boundary nodes: B_0's own fixed total, 19 (the sum of its boundary values, where the
// directional ones give 1 each). Error bound: ||sum e_j|| <= sum eps_j ||B_j||, over ||B_0||.
class AmbientSum {
 public:
  AmbientSum(const ModelPlan& mp) : mp_(mp) {
    for (const SolutionPlan& s : mp.solutions)
      if (s.derived) plan_ = &s;
    if (!plan_) return;
    for (auto& c : sum_) c.assign(mp.lattice.dims.count(), 0.0);
  }
  bool wanted() const { return plan_ != nullptr; }

  void add(const SolutionResult& r) {
    if (!plan_ || r.plan.index < 1) return;
    const auto t0 = Clock::now();
    double norm_sq = 0, peak = 0;
    for (int c = 0; c < kChannels; ++c) {
      const std::vector<float>& t = r.totals[c];
      for (std::size_t i = 0; i < t.size(); ++i) {
        sum_[c][i] += t[i];
        norm_sq += static_cast<double>(t[i]) * t[i];
        peak = std::max(peak, static_cast<double>(t[i]));
      }
    }
    bound_ += r.error_estimate * std::sqrt(norm_sq);
    bound_max_ += r.error_estimate_max * peak;
    iterations_ = std::max(iterations_, r.iterations);
    converged_ = converged_ && r.converged;
    ++count_;
    seconds_ += std::chrono::duration<double>(Clock::now() - t0).count();
  }

  // After all 18 directional solutions.
  void finish(BakeObserver& observer) {
    if (!plan_) return;
    if (count_ != 18) throw Error(ErrorCategory::Internal, "B00 from the sum: expected 18 directional solutions");
    const auto t0 = Clock::now();
    SolutionResult r;
    r.plan = *plan_;
    const Dims& d = mp_.lattice.dims;
    double norm_sq = 0, max_value = 0;
    for (int c = 0; c < kChannels; ++c) {
      r.totals[c].resize(d.count());
      for (int z = 0; z < d.nz; ++z)
        for (int y = 0; y < d.ny; ++y)
          for (int x = 0; x < d.nx; ++x) {
            const std::size_t i = d.index(x, y, z);
            const double v = d.is_boundary(x, y, z) ? 19.0 : sum_[c][i];
            r.totals[c][i] = static_cast<float>(v);
            norm_sq += v * v;
            max_value = std::max(max_value, v);
          }
    }
    r.iterations = iterations_;
    r.converged = converged_;
    r.error_estimate = norm_sq > 0 ? bound_ / std::sqrt(norm_sq) : 0.0;
    r.error_estimate_max = max_value > 0 ? bound_max_ / max_value : 0.0;
    r.seconds = seconds_ + std::chrono::duration<double>(Clock::now() - t0).count();
    for (auto& c : sum_) std::vector<double>().swap(c);
    observer.solution_done(mp_, r);
  }

 private:
  const ModelPlan& mp_;
  const SolutionPlan* plan_ = nullptr;
  std::array<std::vector<double>, 3> sum_;
  double bound_ = 0, bound_max_ = 0, seconds_ = 0;
  int iterations_ = 0, count_ = 0;
  bool converged_ = true;
};

}  // namespace

// An uneven last batch would step as often as the others with a fraction of the device busy.
int balanced_batch(int total, int capacity, int channels) {
  capacity = std::max(1, capacity);
  channels = std::max(1, channels);
  if (total <= capacity) return std::max(1, total);
  const int batches = (total + capacity - 1) / capacity;
  int even = (total + batches - 1) / batches;
  if (capacity % channels == 0) even = (even + channels - 1) / channels * channels;  // still <= capacity
  return even;
}

// Krylov solves take one system at a time (their vectors belong to system 0).
int batch_capacity(const ModelPlan& mp, const Backend& backend, const BakeOptions& opt) {
  const Dims& d = mp.lattice.dims;
  const std::size_t per_system = backend.bytes_per_system(d, opt.precision);
  const std::size_t fixed = backend.bytes_per_lattice(d);
  const std::size_t avail = backend.available_bytes();
  const int channels = std::max(1, static_cast<int>(mp.channels.size()));
  const int total = static_cast<int>(mp.systems());
  const bool krylov = mp.steps.method == SolverMethod::BiCGStab;
  int want = opt.max_systems > 0 ? opt.max_systems : backend.preferred_batch(d, opt.precision, total);
  want = krylov ? 1 : std::max(1, std::min(want, total));
  // A backend's own choice covers at least one whole solution (its channels share the launch).
  if (!krylov && opt.max_systems <= 0) want = std::max(want, std::min(channels, total));
  // Krylov vectors: 8 more state-sized arrays (about 4 systems' worth).
  const std::size_t extra = krylov ? 4 * per_system : 0;
  if (avail > 0) {
    // keep a tenth of the free memory for everything else
    const double usable = 0.9 * static_cast<double>(avail) - static_cast<double>(fixed + extra);
    const int fit = usable > 0 ? static_cast<int>(usable / static_cast<double>(per_system)) : 0;
    if (fit < 1)
      throw Error(ErrorCategory::Unavailable,
                  "model '" + mp.spec->name + "': a " + std::to_string(d.nx) + "x" + std::to_string(d.ny) + "x" +
                      std::to_string(d.nz) + " lattice needs " + gib(fixed + extra + per_system) + " on the " +
                      backend.name() + " backend but only " + gib(avail) +
                      " is available; lower the resolution or use a machine with more memory");
    want = std::min(want, fit);
  }
  if (want > channels) want -= want % channels;  // whole solutions per batch
  return balanced_batch(total, want, channels);
}

void bake_model(const ModelPlan& mp, const Backend& backend, const BakeOptions& opt, BakeObserver& observer) {
  if (mp.steps.method == SolverMethod::BiCGStab && mp.steps.mode != IterationMode::Auto)
    throw_invalid("solver method bicgstab needs iterations \"auto\" (it stops on the error estimate)");
  const int capacity = batch_capacity(mp, backend, opt);
  SolverOptions so;
  so.precision = opt.precision;
  so.max_systems = capacity;
  auto solver = backend.create(mp.lattice, mp.channels, so);
  if (mp.steps.method == SolverMethod::BiCGStab) krylov_vectors_of(*solver, backend.name());  // offered, or stop here
  observer.model_started(mp, backend, solver->bytes_in_use());

  std::vector<SystemRef> queue;
  for (int s = 0; s < static_cast<int>(mp.solutions.size()); ++s)
    if (!mp.solutions[static_cast<std::size_t>(s)].derived)
      for (int c = 0; c < static_cast<int>(mp.channels.size()); ++c) queue.push_back({s, c});
  AmbientSum ambient(mp);

  // Per solution, what its channels have produced so far (channels may run in separate batches
  // when memory is short or a Krylov solver takes one system at a time).
  struct Pending {
    std::vector<std::vector<float>> per_channel;
    int channels_done = 0, iterations = 0, krylov_iterations = 0;
    double seconds = 0, error_estimate = 0, error_estimate_max = 0, krylov_residual = 0;
    bool converged = true;
    std::vector<CheckPoint> history;
  };
  std::vector<Pending> pending(mp.solutions.size());
  for (Pending& p : pending) p.per_channel.resize(mp.channels.size());
  const std::size_t count = mp.lattice.dims.count();
  const bool fixed = mp.steps.mode != IterationMode::Auto;

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

    solver->reset(batch);
    BatchRunner runner(mp, *solver, opt, observer, batch_solutions, batch.size());
    BatchOutcome outcome = mp.steps.method == SolverMethod::BiCGStab ? runner.krylov() : runner.plain();
    const double batch_seconds = runner.seconds();
    observer.memory_in_use(mp, solver->bytes_in_use());

    // Collect each system's totals; a solution is done once all its channels are.
    for (std::size_t s = 0; s < batch.size(); ++s) {
      const int sol = queue[start + s].solution;
      Pending& p = pending[static_cast<std::size_t>(sol)];
      auto& buf = p.per_channel[static_cast<std::size_t>(batch[s].channel)];
      buf.resize(count);
      solver->read_totals(static_cast<int>(s), buf.data());
      ++p.channels_done;
      p.iterations = std::max(p.iterations, outcome.steps);
      p.krylov_iterations = std::max(p.krylov_iterations, outcome.krylov_iterations);
      p.krylov_residual = std::max(p.krylov_residual, outcome.krylov_residual);
      p.seconds += batch_seconds / static_cast<double>(batch.size());
      const double estimate = std::min(outcome.monitors[s].error_estimate(), outcome.latched[s]);
      if (p.history.empty() || estimate >= p.error_estimate) p.history = outcome.worst_history;
      p.error_estimate = std::max(p.error_estimate, estimate);
      p.error_estimate_max =
          std::max(p.error_estimate_max, std::min(outcome.monitors[s].error_estimate_max(), outcome.latched_max[s]));
      p.converged = p.converged && outcome.converged;
      if (p.channels_done < static_cast<int>(mp.channels.size())) continue;
      SolutionResult r;
      r.plan = mp.solutions[static_cast<std::size_t>(sol)];
      r.iterations = p.iterations;
      r.seconds = p.seconds;
      r.error_estimate = p.error_estimate;
      r.error_estimate_max = p.error_estimate_max;
      r.converged = !fixed && p.converged;
      r.krylov_iterations = p.krylov_iterations;
      r.krylov_residual = p.krylov_residual;
      r.history = std::move(p.history);
      for (int c = 0; c < kChannels; ++c) r.totals[c] = p.per_channel[static_cast<std::size_t>(mp.channel_of[c])];
      p = Pending{};
      ambient.add(r);
      observer.solution_done(mp, r);
    }
    start = end;
  }
  ambient.finish(observer);
}

}  // namespace lblight
