// A bake's work units as a Slurm job array (docs/scale-out.md): `lblight submit` writes a
// submission folder and sbatch scripts, `lblight status` reads what the jobs leave there.
//
//   OUT/submit.json          the scene, the units (name, inputs hash, estimates) and the submissions
//   OUT/slurm/units.sbatch   one array task per unit: lblight bake --only UNIT -o OUT/parts/UNIT
//   OUT/slurm/merge.sbatch   lblight merge of every part into OUT/bake, after the array (afterok)
//   OUT/parts/<unit>/        the partial outputs (a finished unit is its partial)
//   OUT/state/<unit>.json    queued / running / failed (exit code, host, log), from the scripts
//   OUT/logs/                one log per unit and attempt, and the merge's
//   OUT/bake/                the merged output
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lblight/backend/backend.h"
#include "lblight/solve/plan.h"

namespace lblight {

// What one array task needs, from the plan (plan_cost, as validate prints it).
struct UnitEstimate {
  std::string name, hash;
  double memory_bytes = 0;  // host memory of the task: solver state on the CPU, lattice, output buffers
  double seconds = 0;       // 0 when the throughput was not measured
};

// The host memory a unit's task needs: on the CPU the solver's (plan_cost), plus
// host_bytes_per_node (solve/plan.h) and the output's grid buffers per node, plus the process itself.
double unit_memory_bytes(const ModelPlan& model, const Backend& sizing_backend, bool solver_on_host);

struct SlurmSettings {
  std::string partition, account;
  std::string time, mem;  // sbatch values; empty: from the estimates
  int cpus_per_task = 1;
  int gpus_per_task = 0;
  int max_parallel = 0;   // array tasks at once (%K); 0: no limit
  std::vector<std::string> sbatch_args;  // more #SBATCH lines, as given ("--qos=long")
};

struct Submission {
  std::filesystem::path out;       // absolute
  std::filesystem::path lblight;   // the executable the jobs run (absolute)
  std::filesystem::path scene_file;  // absolute
  std::string scene_name, scene_hash;
  std::string backend = "cpu";     // cpu | cuda
  std::vector<std::string> bake_args;  // solve options passed on to every unit's bake
  std::vector<UnitEstimate> units;
  SlurmSettings slurm;
  nlohmann::json submissions = nlohmann::json::array();  // one record per sbatch of the array
};

// Slurm's formats: "D-HH:MM:SS" for a time limit (whole minutes, rounded up) and "<MiB>M".
std::string slurm_time(double seconds);
std::string slurm_mem(double bytes);
// The time limit of a task that is estimated at `seconds` (0: unknown): twice that, plus start-up,
// at least 10 minutes.
double task_time_limit(double seconds);
// Array indices as Slurm ranges: {0, 1, 2, 5} -> "0-2,5".
std::string array_ranges(const std::vector<int>& indices);

std::filesystem::path submission_file(const std::filesystem::path& out);
std::filesystem::path part_dir(const std::filesystem::path& out, const std::string& unit);
std::filesystem::path state_file(const std::filesystem::path& out, const std::string& unit);
std::filesystem::path merged_dir(const std::filesystem::path& out);

// Checks that `out` may hold a submission of scene `scene_name`: absent, empty, or a previous
// submission (submit.json) of a scene of that name. Error(InvalidInput) naming what is in the way.
void check_submission_folder(const std::filesystem::path& out, const std::string& scene_name);

// Error(InvalidInput) when a value the scripts would receive (paths, options, --partition,
// --account, --time, --mem, --sbatch-arg, unit names) holds a control character, or --time/--mem
// is not in Slurm's format. write_submission checks this first; submit calls it before its
// estimates.
void check_script_values(const Submission& s);

// Writes submit.json and both scripts (creating the folders); `resume`: the tasks bake with
// --resume. Returns the paths of the array and merge scripts.
std::pair<std::filesystem::path, std::filesystem::path> write_submission(const Submission& s, bool resume);
Submission read_submission(const std::filesystem::path& out);
void save_submission(const Submission& s);  // submit.json only (after sbatch: the job ids)

// Marks units as queued by `job` (their state files), so that status does not show an old failure.
void mark_queued(const Submission& s, const std::vector<int>& units, const std::string& job);

// Runs sbatch with `args` and returns the job id it prints (--parsable). Error(Unavailable) when
// sbatch is not there, Error(Io) with its message when it fails.
std::string run_sbatch(const std::vector<std::string>& args);

struct UnitStatus {
  std::string name;
  std::string state;   // done, running, queued, failed, missing
  std::string detail;  // where, since when, exit code, log
};
// Reads the parts (by size, without checksums: a merge or bake --resume verifies those) and the
// state files; not Slurm's accounting.
std::vector<UnitStatus> submission_status(const Submission& s);
// The merged output's state: "" when OUT/bake is absent, else a line saying what it holds.
std::string merged_status(const Submission& s);

}  // namespace lblight
