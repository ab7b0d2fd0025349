// lblight submit: a scene's bake as a Slurm job array over its work units plus a dependent merge
// (docs/scale-out.md).
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <iostream>
#include <memory>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "apps/lblight/solve_options.h"
#include "lblight/core/error.h"
#include "lblight/core/script_text.h"
#include "lblight/core/system_info.h"
#include "lblight/io/output_dir.h"
#include "lblight/pipeline/slurm.h"
#include "lblight/pipeline/work_units.h"
#include "lblight/solve/plan_cost.h"
#include "lblight/solve/throughput.h"

namespace fs = std::filesystem;

namespace lblight::cli {
namespace {

struct SubmitArgs {
  SolveOptions solve;
  bool slurm = false;
  std::string output, lblight;
  bool dry_run = false, resume = false, no_timing = false;
  SlurmSettings settings;
  int cpus_per_task = 0;  // 0: 4 on the CPU, 2 beside a GPU
};

fs::path this_executable() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw Error(ErrorCategory::Unavailable, "cannot find lblight's own path (/proc/self/exe); give --lblight PATH");
  return exe;
}

// What every unit needs: its inputs hash, and memory and time as validate estimates them (the
// throughput measured here, on as many threads as a task gets).
std::vector<UnitEstimate> estimate_units(const BakePlan& plan, const SubmitArgs& a, const std::string& backend_name) {
  BackendRequest req;
  req.name = "cpu";
  req.threads = usable_threads(a.settings.cpus_per_task);
  const auto sizing = make_backend(req);
  const bool timed = !a.no_timing && a.settings.time.empty();
  const Precision timing_precision = sizing->supports(plan.precision) ? plan.precision : Precision::Float32;
  const double ups = timed ? measure_updates_per_second(*sizing, timing_precision) : 0.0;
  // The coarse forest lattices are made from every model's grid: their task loads all of them.
  double model_grid_bytes = 0;
  for (const ModelPlan& mp : plan.models)
    if (mp.role == PlanRole::Model)
      model_grid_bytes += 5.0 * static_cast<double>(mp.grid.dims.count() + mp.lattice.dims.count());
  std::vector<UnitEstimate> units;
  for (const ModelPlan& mp : plan.models) {
    UnitEstimate u;
    u.name = mp.spec->name;
    u.hash = unit_hash(plan, mp, backend_name);
    u.memory_bytes = unit_memory_bytes(mp, *sizing, backend_name == "cpu") +
                     (mp.role == PlanRole::Model ? 0.0 : model_grid_bytes);
    u.seconds = plan_cost(mp, *sizing).seconds(ups, host_cores());
    units.push_back(u);
  }
  return units;
}

int run_submit(SubmitArgs a) {
  if (!a.slurm) throw_invalid("say which scheduler: --slurm (the only one lblight submits to)", {"--slurm", {}, {}});
  const Scene scene = load_scene(a.solve.scene);
  const fs::path out = fs::absolute(output_folder_path(a.output)).lexically_normal();
  check_scene_output(scene, out);
  check_submission_folder(out, scene.name);
  // The backend every unit runs on (part of its inputs hash): a GPU asked for means CUDA.
  std::string backend = a.solve.backend == "auto" ? (a.settings.gpus_per_task > 0 ? "cuda" : "cpu") : a.solve.backend;
  if (backend == "cpu" && a.settings.gpus_per_task > 0)
    throw_invalid("--gpus-per-task " + std::to_string(a.settings.gpus_per_task) +
                      " with --backend cpu; allowed: --backend cuda (or auto) with GPUs, none with cpu",
                  {"--gpus-per-task", {}, {}});
  if (backend == "cuda" && a.settings.gpus_per_task == 0) a.settings.gpus_per_task = 1;
  a.settings.cpus_per_task = a.cpus_per_task > 0 ? a.cpus_per_task : backend == "cuda" ? 2 : 4;

  PlanOverrides ov = a.solve.overrides();
  const BakePlan plan = make_plan(scene, ov, a.solve.run_context());
  for (const std::string& w : plan.warnings) spdlog::warn("{}", w);

  Submission s;
  if (std::filesystem::exists(submission_file(out))) s.submissions = read_submission(out).submissions;
  s.out = out;
  s.lblight = a.lblight.empty() ? this_executable() : fs::absolute(a.lblight);
  s.scene_file = fs::absolute(scene.file).lexically_normal();
  s.scene_name = scene.name;
  s.scene_hash = scene.hash;
  s.backend = backend;
  s.bake_args = a.solve.plan_arguments();
  s.slurm = a.settings;
  check_script_values(s);
  s.units = estimate_units(plan, a, backend);

  // The units to run: all, or with --resume those without a finished partial.
  std::vector<int> run;
  Table table({"unit", "memory", "estimated time", "inputs hash", "this submission"});
  for (std::size_t i = 0; i < s.units.size(); ++i) {
    const UnitEstimate& u = s.units[i];
    const bool done =
        a.resume && check_part(part_dir(out, u.name), u.name, u.hash, /*verify_checksums=*/true).state == PartState::Done;
    if (done) spdlog::info("unit '{}': finished in {} (inputs hash {}), not resubmitted", u.name,
                           part_dir(out, u.name).string(), u.hash);
    else run.push_back(static_cast<int>(i));
    table.add({u.name, format_bytes(u.memory_bytes), u.seconds > 0 ? format_seconds(u.seconds) + " s" : "-", u.hash,
               done ? "done: skipped" : "array task " + std::to_string(i)});
  }
  const auto [array_script, merge_script] = write_submission(s, a.resume);
  std::cout << table.str();

  std::string array_arg = "--array=" + array_ranges(run);
  if (a.settings.max_parallel > 0) array_arg += "%" + std::to_string(a.settings.max_parallel);
  if (a.dry_run) {
    std::cout << "dry run: wrote " << array_script.string() << " and " << merge_script.string()
              << "; nothing submitted. To submit by hand:\n";
    if (run.empty())
      std::cout << "  sbatch " << shell_word(merge_script.string()) << "\n";
    else
      std::cout << "  array=$(sbatch --parsable " << array_arg << " " << shell_word(array_script.string())
                << ") && sbatch --dependency=afterok:${array%%;*} " << shell_word(merge_script.string()) << "\n";
    return 0;
  }
  std::string array_job;
  if (!run.empty()) {
    array_job = run_sbatch({array_arg, array_script.string()});
    mark_queued(s, run, array_job);
  }
  const std::string merge_job =
      run.empty() ? run_sbatch({merge_script.string()})
                  : run_sbatch({"--dependency=afterok:" + array_job, merge_script.string()});
  s.submissions.push_back({{"time", utc_timestamp()},
                           {"array_job", array_job},
                           {"array", run.empty() ? "" : array_ranges(run)},
                           {"merge_job", merge_job}});
  save_submission(s);
  if (run.empty())
    std::cout << "every unit is done: submitted the merge only, job " << merge_job << "\n";
  else
    std::cout << "submitted array job " << array_job << " (" << run.size() << " of " << s.units.size()
              << " unit(s)) and merge job " << merge_job << " after it; output: " << merged_dir(out).string()
              << "\nprogress: lblight status " << shell_word(out.string()) << "\n";
  // For scripts: the job ids alone on the last line.
  std::cout << "jobs: " << (array_job.empty() ? "-" : array_job) << " " << merge_job << "\n";
  return 0;
}

}  // namespace

Command add_submit_command(CLI::App& app, const GlobalOptions&) {
  auto args = std::make_shared<SubmitArgs>();
  CLI::App* cmd = app.add_subcommand(
      "submit",
      "Bake a scene on a Slurm cluster: one array task per work unit (each model, the coarse forest lattices) "
      "writing OUTDIR/parts/<unit>, and a merge job after them (afterok) writing OUTDIR/bake, exactly what one "
      "`lblight bake` writes. Memory and time per task come from the plan's estimates (lblight validate). "
      "`lblight status OUTDIR` shows the units' progress (docs/scale-out.md).");
  args->solve.add_plan_options(*cmd);
  cmd->add_flag("--slurm", args->slurm, "Submit to Slurm (sbatch); required")->required();
  cmd->add_option("-o,--output", args->output,
                  "Submission folder (scripts, parts, logs, the merged bake in OUTDIR/bake); new, empty or a previous "
                  "submission's")
      ->required()
      ->check(kNonEmpty);
  cmd->add_option("--backend", args->solve.backend,
                  "Backend of every unit: cpu, cuda (requests GPUs), or auto: cuda when --gpus-per-task is given")
      ->check(CLI::IsMember({"auto", "cpu", "cuda"}))
      ->capture_default_str();
  cmd->add_option("--partition", args->settings.partition, "Slurm partition (default: the cluster's)")->check(kNonEmpty);
  cmd->add_option("--account", args->settings.account, "Slurm account to charge")->check(kNonEmpty);
  cmd->add_option("--time", args->settings.time,
                  "Time limit per task, as sbatch takes it (default: twice the largest unit's estimate plus 2 "
                  "minutes, at least 10 minutes)")
      ->check(kNonEmpty);
  cmd->add_option("--mem", args->settings.mem,
                  "Memory per task, as sbatch takes it (default: the largest unit's estimate, with a 25% margin)")
      ->check(kNonEmpty);
  cmd->add_option("--cpus-per-task", args->cpus_per_task, "CPU threads per task (default: 4 on cpu, 2 beside a GPU)")
      ->check(CLI::Range(1, 4096));
  cmd->add_option("--gpus-per-task", args->settings.gpus_per_task, "GPUs per task (default: 1 with --backend cuda)")
      ->check(CLI::Range(0, 64));
  cmd->add_option("--max-parallel", args->settings.max_parallel, "Array tasks running at once (default: no limit)")
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--sbatch-arg", args->settings.sbatch_args,
                  "Another #SBATCH line for both scripts, e.g. --sbatch-arg=--qos=long (repeatable)")
      ->check(kNonEmpty);
  cmd->add_option("--lblight", args->lblight, "The lblight executable the jobs run (default: this one)")
      ->check(kNonEmpty);
  cmd->add_flag("--resume", args->resume,
                "Submit only the units without a finished partial in OUTDIR/parts (same inputs hash); their tasks "
                "bake with --resume");
  cmd->add_flag("--dry-run", args->dry_run, "Write the scripts and print the sbatch commands; submit nothing");
  cmd->add_flag("--no-timing", args->no_timing, "Skip the throughput measurement behind the time estimate");
  return {cmd, [args] { return run_submit(*args); }};
}

}  // namespace lblight::cli
