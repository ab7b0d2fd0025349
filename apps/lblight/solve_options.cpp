#include "apps/lblight/solve_options.h"

#include <CLI/CLI.hpp>

#include <cstdio>

#include "apps/lblight/cli_support.h"
#include "lblight/core/error.h"

namespace lblight::cli {

void SolveOptions::add_to(CLI::App& cmd) {
  add_plan_options(cmd);
  cmd.add_option("--backend", backend,
                 "Compute backend: auto (GPU when one is usable, else CPU), cpu (OpenMP), cuda, or mpi (one lattice "
                 "split across the ranks of mpirun/srun, each running --threads OpenMP threads; plain iteration; "
                 "rank 0 writes the output: docs/scale-out.md)")
      ->check(CLI::IsMember({"auto", "cpu", "cuda", "mpi"}))
      ->capture_default_str();
  cmd.add_option("--threads", threads, "CPU threads (0 = OMP_NUM_THREADS or all cores)")
      ->check(CLI::Range(0, 4096))
      ->capture_default_str();
  cmd.add_option("--device", device, "GPU ordinal for --backend cuda")->check(CLI::Range(0, 64))->capture_default_str();
}

void SolveOptions::add_plan_options(CLI::App& cmd) {
  cmd.add_option("scene", scene, "Scene file (JSON, format v1: docs/scene-format.md)")->required();
  cmd.add_option("--solutions", solutions,
                 "Base solutions to bake: 'all' or indices/ranges such as 0,1,5-7 (default: the scene's)")
      ->check(kNonEmpty);
  cmd.add_option("--iterations", iterations,
                 "Steps per solution: 'auto' (until the error estimate is below --tolerance), 'paper' "
                 "(2 x longest lattice edge, [Geist2010] sec. 3.1), or a fixed count (default: the scene's)")
      ->check(kNonEmpty);
  cmd.add_option("--tolerance", tolerance,
                 "Target relative error for --iterations auto (default: the scene's, else 1e-4)")
      ->check(finite_range(1e-15, 0.5));
  cmd.add_option("--method", method,
                 "Steady-state solver: plain (iterate the LB step, as the papers), bicgstab (Krylov solver for "
                 "the same fixed point) or dsa (LB steps corrected by a multigrid diffusion solve: thick "
                 "scattering media, docs/accuracy.md); bicgstab and dsa need --iterations auto (default: the scene's)")
      ->check(CLI::IsMember({"plain", "bicgstab", "dsa"}));
  cmd.add_option("--precision", precision, "Lattice storage: float32, float64 (cpu only) or float16 (arithmetic in float32; docs/accuracy.md)")
      ->check(CLI::IsMember({"float32", "float64", "float16"}));
  cmd.add_option("--state", state,
                 "Lattice state in memory: two-levels (two copies, needed for the CPU's temporal blocking), "
                 "in-place (one copy updated by the AA pattern: half the memory, the same results; cpu and cuda backends) "
                 "or auto (in place where only that fits or where the backend runs it faster; default: the scene's)")
      ->check(CLI::IsMember({"auto", "two-levels", "in-place"}));
}

PlanOverrides SolveOptions::overrides() const {
  PlanOverrides ov;
  if (!solutions.empty()) ov.solutions = parse_solution_list(solutions, {"--solutions", {}, {}});
  if (!iterations.empty()) {
    IterationMode mode = IterationMode::Auto;
    int steps = 0;
    parse_iterations(iterations, mode, steps);
    ov.mode = mode;
    ov.iterations = steps;
  }
  if (tolerance > 0) ov.tolerance = tolerance;
  if (!precision.empty()) ov.precision = parse_precision(precision);
  if (!method.empty()) ov.method = parse_solver_method(method).value_or(SolverMethod::Plain);
  if (!state.empty() && state != "auto") ov.state = parse_state_layout(state);
  return ov;
}

std::vector<std::string> SolveOptions::plan_arguments() const {
  std::vector<std::string> args;
  const auto pass = [&](const char* flag, const std::string& value) {
    if (!value.empty()) args.insert(args.end(), {flag, value});
  };
  pass("--solutions", solutions);
  pass("--iterations", iterations);
  if (tolerance > 0) {
    char exact[32];  // every digit: the units' plans must be this plan
    std::snprintf(exact, sizeof exact, "%.17g", tolerance);
    pass("--tolerance", exact);
  }
  pass("--precision", precision);
  pass("--method", method);
  pass("--state", state);
  return args;
}

RunContext SolveOptions::run_context() const {
  RunContext ctx;
  ctx.cancel = &g_interrupted;
  ctx.threads = usable_threads(threads);
  return ctx;
}

std::unique_ptr<Backend> SolveOptions::make_backend(const char* command) const {
  // One lattice across ranks is what a bake needs; a report or a gas sequence on every rank would
  // write the same output from each.
  if (backend == "mpi" && std::string(command) != "bake")
    throw_invalid(std::string("--backend mpi runs `lblight bake` across MPI ranks, not `lblight ") + command +
                  "`; use --backend cpu or cuda (docs/scale-out.md)");
  BackendRequest req;
  req.name = backend;
  req.threads = usable_threads(threads);
  req.device = device;
  return lblight::make_backend(req);
}

}  // namespace lblight::cli
