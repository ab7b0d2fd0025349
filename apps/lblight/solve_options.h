// Options that bake and validate share: the scene, the backend and the solve overrides.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "backends/registry.h"
#include "lblight/solve/plan.h"

namespace CLI {
class App;
}

namespace lblight::cli {

struct SolveOptions {
  std::string scene;
  std::string backend = "auto";
  int threads = 0;
  int device = 0;
  std::string solutions;   // empty = the scene's
  std::string iterations;  // empty = the scene's
  double tolerance = 0;    // 0 = the scene's
  std::string precision;   // empty = the scene's
  std::string method;      // empty = the scene's
  std::string state;       // empty = the scene's

  void add_to(CLI::App& cmd);
  // The scene and what changes its plan (--solutions, --iterations, --tolerance, --method,
  // --precision), without the backend's options: add_to adds both.
  void add_plan_options(CLI::App& cmd);
  PlanOverrides overrides() const;
  // The plan options given, as arguments to pass on to another lblight command.
  std::vector<std::string> plan_arguments() const;
  // Cancelled by the CLI's signal handlers; host threads from --threads.
  RunContext run_context() const;
  // command: the subcommand asking ("bake", "report", ...): --backend mpi is for bake only.
  std::unique_ptr<Backend> make_backend(const char* command) const;
};

}  // namespace lblight::cli
