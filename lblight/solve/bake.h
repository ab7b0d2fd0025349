// Runs a plan on a backend: batches of systems (solution x distinct channel), each iterated to
// its step policy with convergence measured on the backend, results handed to an observer.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "lblight/backend/backend.h"
#include "lblight/core/run_context.h"
#include "lblight/solve/convergence.h"
#include "lblight/solve/flux.h"
#include "lblight/solve/plan.h"

namespace lblight {

struct SolutionResult {
  SolutionPlan plan;
  int iterations = 0;
  double seconds = 0;          // wall time of its batch, shared evenly by the solutions in it
  double error_estimate = 0;   // relative L2, the worst channel (inf = not estimable)
  double error_estimate_max = 0;  // relative max norm, the worst channel
  bool converged = false;      // Auto: reached the tolerance; Fixed/Paper: not applicable (false)
  bool warm_start = false;     // started from a previous solve's state (BakeOptions::warm)
  int krylov_iterations = 0;   // BiCGStab iterations (method bicgstab)
  double krylov_residual = 0;  // its final relative residual
  std::vector<CheckPoint> history;                    // worst channel at every check
  std::array<std::vector<float>, 3> totals;           // R, G, B per lattice node
  // BakeOptions::moments: the flux vector of each colour channel per lattice node (flux.h); empty
  // when not asked for or not available (a backend without state access).
  std::array<FluxField, 3> flux;
  // The Monte Carlo reference only (lblight/reference): the totals' standard error per node, and
  // the photons traced.
  std::array<std::vector<float>, 3> std_error;
  std::uint64_t photons = 0;
};

struct BakeProgress {
  const ModelPlan* model = nullptr;
  std::vector<const SolutionPlan*> batch;
  int step = 0;
  int planned_steps = 0;       // Fixed/Paper: exact; Auto: the cap
  double error_estimate = 0;
  double seconds = 0;
  double error_estimate_max = 0;  // max-norm estimate (worst system)
};

class BakeObserver {
 public:
  virtual ~BakeObserver() = default;
  // bytes: what the solver holds on its device once created (the lattice; a backend may
  // allocate its systems' state only when a batch starts); layout: how it keeps the state.
  virtual void model_started(const ModelPlan&, const Backend&, std::size_t /*bytes*/, StateLayout /*layout*/) {}
  // After each batch: the solver's device memory then (state, totals, Krylov vectors included).
  // Solvers never give memory back while a model solves, so the last report is the peak.
  virtual void memory_in_use(const ModelPlan&, std::size_t /*bytes*/) {}
  virtual void progress(const BakeProgress&) {}
  // The result may be moved from.
  virtual void solution_done(const ModelPlan& model, SolutionResult& result) = 0;

  // Reports only: look at the solver after every convergence check (totals fresh: measured is
  // true) and, when wants_iterates(), after every Krylov iteration (the state is the iterate;
  // call measure() before reading totals). Time spent here should be subtracted by the observer.
  virtual bool wants_iterates() const { return false; }
  virtual void inspect(const BakeProgress&, LatticeSolver&, bool /*measured*/) {}
};

// The final states of a model's systems, carried from one bake_model call to the next on the same
// lattice box (a gas sequence's frames, docs/fluid.md): each system then starts where the previous
// call's stopped instead of from zero. Floats: a starting point needs no more, since the iteration
// converges to its own fixed point from any start (float64 bakes start from the rounded state).
struct WarmStart {
  Dims dims;                                // the lattice the states belong to
  std::vector<std::vector<float>> states;   // per system in bake order: 19 x dims.count(), direction-major
};

struct BakeOptions {
  int max_systems = 0;  // per batch; 0 = as memory allows
  // Only these base solutions (indices 0..18, none derived): a work unit's share of the model
  // (docs/scale-out.md). They must be whole batches of the model's own batching (solution_batches:
  // a batch runs until its slowest system is done), so each comes out exactly as in a bake of the
  // whole model; a B00 summed from B01..B18 is then left to whoever has all of them. Empty: all.
  std::vector<int> solutions;
  // Iterations "auto" only: start every system from warm->states when they are of this lattice
  // and this many systems (else from zero), and leave each system's final state there. Needs the
  // backend's StateAccess (Error(Unavailable) otherwise). A warm start has no minimum step count:
  // docs/fluid.md, "Warm starts", says why the convergence estimate alone is an honest stop then.
  WarmStart* warm = nullptr;
  // The flux of every solution as well (SolutionResult::flux; docs/model.md sec. 3.2), read from
  // the final states. A B00 solved from a source (first_collision), whose state is not its whole
  // light, gets the sum of the 18 directional solutions' flux (the lattice's own B00) when the bake
  // has them all, and none otherwise. Skipped, with a warning, on a backend without StateAccess.
  bool moments = false;
};

// Systems per batch for `model` on `backend`: the backend's preference (or options.max_systems),
// at least one whole solution when the backend chooses, whole solutions where possible, within
// the device's free memory (Error(Unavailable) when not even one system fits), then evened out.
// Each system's state in the layout state_layout() picks.
int batch_capacity(const ModelPlan& model, const Backend& backend, const BakeOptions& options);
// The state layout bake_model creates its solver with: the plan's (model.steps.state; in place
// on a backend without it is Error(Unavailable)); else, where the backend offers in place, in
// place when the device's free memory holds fewer than one whole solution's systems with two
// levels or when the backend runs the lattice faster so (Backend::prefers_in_place); else two levels.
StateLayout state_layout(const ModelPlan& model, const Backend& backend, const BakeOptions& options);
// The smallest batch size that needs no more batches than `capacity` does, a multiple of
// `channels` when `capacity` is: 57 systems at capacity 18 run as 15+15+15+12.
int balanced_batch(int total, int capacity, int channels);

// The base solution indices of each batch bake_model runs for `model` (whole model; derived
// solutions are in none).
std::vector<std::vector<int>> solution_batches(const ModelPlan& model, const Backend& backend, const BakeOptions& options);


// Solves every solution of `model` in its plan's precision (model.steps.precision) and hands each
// to the observer as its last channel finishes. Stops with Error(Cancelled) at the next check once
// ctx.cancel is set.
void bake_model(const ModelPlan& model, const Backend& backend, const BakeOptions& options, BakeObserver& observer,
                const RunContext& ctx = {});

}  // namespace lblight
