#include "lblight/pipeline/slurm.h"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <regex>
#include <sstream>

#include "lblight/core/error.h"
#include "lblight/core/input_file.h"
#include "lblight/core/script_text.h"
#include "lblight/core/system_info.h"
#include "lblight/core/version.h"
#include "lblight/io/output_dir.h"
#include "lblight/pipeline/manifest.h"
#include "lblight/pipeline/work_units.h"
#include "lblight/scene/json_reader.h"
#include "lblight/solve/plan_cost.h"

extern char** environ;

namespace fs = std::filesystem;

namespace lblight {
namespace {

constexpr int kSubmitFormat = 1;
// Bytes per lattice node of the output's buffers: a solution's totals handed to the writer and the
// OpenVDB trees of up to 4 grids compressing at once.
constexpr double kOutputBytesPerNode = 64.0;
constexpr double kProcessBytes = 128.0 * 1048576.0;  // lblight itself (measured ~50 MiB): libraries, threads
constexpr double kMemoryMargin = 1.25;
constexpr double kMergeMemoryBytes = 1024.0 * 1048576.0;

std::string words(const std::vector<std::string>& v) {
  std::string s;
  for (const std::string& w : v) s += (s.empty() ? "" : " ") + shell_word(w);
  return s;
}

// A job name from the scene's: #SBATCH lines split at spaces, and squeue shows the name as it is.
std::string job_name(const std::string& scene_name, const std::string& suffix = "") {
  std::string n = "lblight-" + scene_name + suffix;
  for (char& c : n)
    if (!std::isalnum(static_cast<unsigned char>(c)) && !std::strchr("_-.", c)) c = '_';
  return n;
}

// Text for a script's comment: a line break in a scene's name would end the comment.
std::string one_line(std::string text) {
  for (char& c : text)
    if (static_cast<unsigned char>(c) < 0x20) c = ' ';
  return text;
}

// The #SBATCH lines both scripts share.
void common_directives(std::ostream& o, const SlurmSettings& s) {
  if (!s.partition.empty()) o << "#SBATCH --partition=" << sbatch_word(s.partition) << "\n";
  if (!s.account.empty()) o << "#SBATCH --account=" << sbatch_word(s.account) << "\n";
  for (const std::string& a : s.sbatch_args) o << "#SBATCH " << sbatch_word(a) << "\n";
}

// A log file for #SBATCH --output: sbatch replaces %A, %a, %j in it, so a '%' of the folder's
// name is written %%.
std::string log_pattern(const fs::path& out, const std::string& file) {
  std::string path = (out / "logs").string() + "/";
  std::string escaped;
  for (char c : path) escaped += c == '%' ? std::string("%%") : std::string(1, c);
  return sbatch_word(escaped + file);
}

// The strict reader scenes and manifests go through: duplicate keys, depth, control characters
// and syntax refused with the file and the field, never the JSON library's own text.
nlohmann::json read_json(const fs::path& file, const std::string& what) {
  return JsonReader::parse_strict(read_input_file(file, what, 64ull << 20), file.string());
}

std::string text_of(const nlohmann::json& j, const char* key) {
  return j.is_object() && j.contains(key) && j[key].is_string() ? j[key].get<std::string>() : std::string();
}

}  // namespace

double unit_memory_bytes(const ModelPlan& mp, const Backend& sizing_backend, bool solver_on_host) {
  const double nodes = static_cast<double>(mp.lattice.dims.count());
  double bytes = kProcessBytes + nodes * (host_bytes_per_node(mp.model, mp.moments) + kOutputBytesPerNode);
  if (solver_on_host) bytes += static_cast<double>(plan_cost(mp, sizing_backend).device_bytes);
  return kMemoryMargin * bytes;
}

std::string slurm_time(double seconds) {
  const long long minutes = std::max(1LL, static_cast<long long>(std::ceil(seconds / 60.0)));
  char buf[32];
  std::snprintf(buf, sizeof buf, "%lld-%02lld:%02lld:00", minutes / 1440, minutes / 60 % 24, minutes % 60);
  return buf;
}

std::string slurm_mem(double bytes) {
  return std::to_string(std::max(1LL, static_cast<long long>(std::ceil(bytes / 1048576.0)))) + "M";
}

double task_time_limit(double seconds) { return std::max(600.0, 2.0 * seconds + 120.0); }

std::string array_ranges(const std::vector<int>& indices) {
  std::string s;
  for (std::size_t i = 0; i < indices.size();) {
    std::size_t j = i;
    while (j + 1 < indices.size() && indices[j + 1] == indices[j] + 1) ++j;
    s += (s.empty() ? "" : ",") + std::to_string(indices[i]) + (j > i ? "-" + std::to_string(indices[j]) : "");
    i = j + 1;
  }
  return s;
}

fs::path submission_file(const fs::path& out) { return out / "submit.json"; }
fs::path part_dir(const fs::path& out, const std::string& unit) { return out / "parts" / unit; }
fs::path state_file(const fs::path& out, const std::string& unit) { return out / "state" / (unit + ".json"); }
fs::path merged_dir(const fs::path& out) { return out / "bake"; }

void check_submission_folder(const fs::path& out, const std::string& scene_name) {
  std::error_code ec;
  if (!fs::exists(out, ec)) return;
  if (!fs::is_directory(out, ec)) throw_invalid("is not a folder; name a folder for the submission", {out.string(), {}, {}});
  if (fs::is_empty(out, ec)) return;
  if (!fs::exists(submission_file(out), ec))
    throw_invalid("holds something other than an lblight submission (no submit.json); name a new or empty folder, or "
                  "a previous submission's",
                  {out.string(), {}, {}});
  const Submission previous = read_submission(out);
  if (previous.scene_name != scene_name)
    throw_invalid("holds a submission of scene '" + previous.scene_name + "', not '" + scene_name +
                      "'; name a new or empty folder",
                  {submission_file(out).string(), "/scene/name", {}});
}

void check_script_values(const Submission& s) {
  check_script_value(s.out.string(), "-o");
  check_script_value(s.lblight.string(), "--lblight");
  check_script_value(s.scene_file.string(), "the scene file");
  check_script_value(s.backend, "--backend");
  for (const std::string& a : s.bake_args) check_script_value(a, "a bake option");
  check_script_value(s.slurm.partition, "--partition");
  check_script_value(s.slurm.account, "--account");
  check_script_value(s.slurm.time, "--time");
  check_script_value(s.slurm.mem, "--mem");
  for (const std::string& a : s.slurm.sbatch_args) check_script_value(a, "--sbatch-arg");
  for (const UnitEstimate& u : s.units) check_script_value(u.name, "unit name");
  static const std::regex time_format(R"(\d+|\d+:\d+|\d+:\d+:\d+|\d+-\d+|\d+-\d+:\d+|\d+-\d+:\d+:\d+|UNLIMITED|unlimited|INFINITE|infinite)");
  if (!s.slurm.time.empty() && !std::regex_match(s.slurm.time, time_format))
    throw_invalid("--time '" + s.slurm.time + "' is not a Slurm time limit; allowed: MINUTES, MINUTES:SECONDS, "
                  "HOURS:MINUTES:SECONDS, DAYS-HOURS[:MINUTES[:SECONDS]] or UNLIMITED",
                  {"--time", {}, {}});
  static const std::regex mem_format(R"(\d{1,12}[KMGT]?)");
  if (!s.slurm.mem.empty() && !std::regex_match(s.slurm.mem, mem_format))
    throw_invalid("--mem '" + s.slurm.mem + "' is not a Slurm memory size; allowed: a whole number of MiB, or with a "
                  "unit K, M, G or T (e.g. 8G)",
                  {"--mem", {}, {}});
}

std::pair<fs::path, fs::path> write_submission(const Submission& s, bool resume) {
  check_script_values(s);
  for (const char* sub : {"slurm", "parts", "state", "logs"}) fs::create_directories(s.out / sub);
  save_submission(s);

  double memory = 0, seconds = 0;
  for (const UnitEstimate& u : s.units) {
    memory = std::max(memory, u.memory_bytes);
    seconds = std::max(seconds, u.seconds);
  }
  const std::string time = s.slurm.time.empty() ? slurm_time(task_time_limit(seconds)) : s.slurm.time;
  const std::string out = s.out.string();
  std::vector<std::string> names;
  for (const UnitEstimate& u : s.units) names.push_back(u.name);

  std::ostringstream a;
  a << "#!/bin/bash\n"
    << "# lblight submit: one array task per work unit of scene '" << one_line(s.scene_name) << "' (docs/scale-out.md).\n"
    << "# Written by lblight " << kVersion << " (rewritten by every submit); lblight status " << one_line(shell_word(out))
    << " reads what it leaves.\n"
    << "#SBATCH --job-name=" << job_name(s.scene_name) << "\n"
    << "#SBATCH --output=" << log_pattern(s.out, "slurm-%A_%a.out") << "\n"
    << "#SBATCH --ntasks=1\n"
    << "#SBATCH --cpus-per-task=" << s.slurm.cpus_per_task << "\n"
    << "#SBATCH --mem=" << sbatch_word(s.slurm.mem.empty() ? slurm_mem(memory) : s.slurm.mem) << "\n"
    << "#SBATCH --time=" << sbatch_word(time) << "\n";
  if (s.slurm.gpus_per_task > 0) a << "#SBATCH --gpus-per-task=" << s.slurm.gpus_per_task << "\n";
  common_directives(a, s.slurm);
  std::vector<std::string> bake = {s.lblight.string(), "bake", s.scene_file.string(), "--only"};
  a << "set -u\n"
    << "units=(" << words(names) << ")\n"
    << "unit=${units[$SLURM_ARRAY_TASK_ID]}\n"
    << "out=" << shell_word(out) << "\n"
    << "job=${SLURM_ARRAY_JOB_ID}_${SLURM_ARRAY_TASK_ID}\n"
    << "log=\"$out/logs/$unit.$job.log\"\n"
    << "# lblight status reads these: running, then failed with the exit code (a finished unit is its partial).\n"
    << "state() {\n"
    << "  printf '{\"state\": \"%s\", \"job\": \"%s\", \"host\": \"%s\", \"time\": \"%s\", \"log\": \"%s\"%s}\\n' \"$1\" "
       "\"$job\" \"$(hostname -s)\" \\\n"
    << "    \"$(date -u +%Y-%m-%dT%H:%M:%SZ)\" \"$log\" \"${2:-}\" >\"$out/state/$unit.json.tmp\" &&\n"
    << "    mv -f \"$out/state/$unit.json.tmp\" \"$out/state/$unit.json\"\n"
    << "}\n"
    << "# A time limit or scancel: lblight stops cleanly on SIGTERM, then the state says failed.\n"
    << "trap 'echo \"unit $unit: terminated\"' TERM\n"
    << "state running\n"
    << "echo \"unit $unit: array task $job on $(hostname -s); log $log\"\n"
    << words(bake) << " \"$unit\" --backend " << shell_word(s.backend) << " --threads \"${SLURM_CPUS_PER_TASK:-0}\""
    << (resume ? " --resume" : "") << (s.bake_args.empty() ? "" : " " + words(s.bake_args))
    << " \\\n  -o \"$out/parts/$unit\" >\"$log\" 2>&1\n"
    << "rc=$?\n"
    << "if [ \"$rc\" -eq 0 ]; then rm -f \"$out/state/$unit.json\"; else state failed \", \\\"exit_code\\\": $rc\"; fi\n"
    << "echo \"unit $unit: exit code $rc\"\n"
    << "exit \"$rc\"\n";

  std::vector<std::string> merge = {s.lblight.string(), "merge", "--scene", s.scene_file.string()};
  for (const std::string& n : names) merge.push_back(part_dir(s.out, n).string());
  merge.push_back("-o");
  merge.push_back(merged_dir(s.out).string());
  std::ostringstream m;
  m << "#!/bin/bash\n"
    << "# lblight submit: the merge of every unit's partial output of scene '" << one_line(s.scene_name)
    << "' into one bake, after the array succeeded (sbatch --dependency=afterok:<array job>).\n"
    << "#SBATCH --job-name=" << job_name(s.scene_name, "-merge") << "\n"
    << "#SBATCH --output=" << log_pattern(s.out, "merge.%j.log") << "\n"
    << "#SBATCH --ntasks=1\n"
    << "#SBATCH --cpus-per-task=1\n"
    << "#SBATCH --mem=" << slurm_mem(kMergeMemoryBytes) << "\n"
    << "#SBATCH --time=" << sbatch_word(time) << "\n"
    << "# A failed unit cancels this job instead of leaving it pending forever (DependencyNeverSatisfied).\n"
    << "#SBATCH --kill-on-invalid-dep=yes\n";
  common_directives(m, s.slurm);
  m << words(merge) << "\n";

  const fs::path array_script = s.out / "slurm" / "units.sbatch", merge_script = s.out / "slurm" / "merge.sbatch";
  write_file_atomically(array_script, a.str());
  write_file_atomically(merge_script, m.str());
  return {array_script, merge_script};
}

void save_submission(const Submission& s) {
  nlohmann::json j;
  j["submit_format"] = kSubmitFormat;
  j["lblight_version"] = kVersion;
  j["lblight"] = s.lblight.string();
  j["scene"] = {{"file", s.scene_file.string()}, {"name", s.scene_name}, {"hash", s.scene_hash}};
  j["backend"] = s.backend;
  j["bake_args"] = s.bake_args;
  j["units"] = nlohmann::json::array();
  for (const UnitEstimate& u : s.units)
    j["units"].push_back(
        {{"name", u.name}, {"hash", u.hash}, {"memory_bytes", u.memory_bytes}, {"estimated_seconds", u.seconds}});
  j["slurm"] = {{"partition", s.slurm.partition}, {"account", s.slurm.account},     {"time", s.slurm.time},
                {"mem", s.slurm.mem},             {"cpus_per_task", s.slurm.cpus_per_task},
                {"gpus_per_task", s.slurm.gpus_per_task}, {"max_parallel", s.slurm.max_parallel},
                {"sbatch_args", s.slurm.sbatch_args}};
  j["submissions"] = s.submissions;
  write_file_atomically(submission_file(s.out), j.dump(2) + "\n");
}

Submission read_submission(const fs::path& out) {
  const fs::path file = submission_file(out);
  check_regular_file(file, "submission file (written by lblight submit)");
  const nlohmann::json j = read_json(file, "submit.json");
  Submission s;
  try {
    if (j.at("submit_format") != kSubmitFormat)
      throw_invalid("submit_format " + j["submit_format"].dump() + " is not " + std::to_string(kSubmitFormat) +
                        "; allowed: a submission written by this lblight",
                    {file.string(), "/submit_format", {}});
    s.out = out;
    s.lblight = j.at("lblight").get<std::string>();
    s.scene_file = j.at("scene").at("file").get<std::string>();
    s.scene_name = j["scene"].at("name").get<std::string>();
    s.scene_hash = j["scene"].at("hash").get<std::string>();
    s.backend = j.at("backend").get<std::string>();
    s.bake_args = j.at("bake_args").get<std::vector<std::string>>();
    for (const auto& u : j.at("units"))
      s.units.push_back({u.at("name").get<std::string>(), u.at("hash").get<std::string>(),
                         u.at("memory_bytes").get<double>(), u.at("estimated_seconds").get<double>()});
    const nlohmann::json& sl = j.at("slurm");
    s.slurm = {sl.at("partition"), sl.at("account"), sl.at("time"), sl.at("mem"), sl.at("cpus_per_task"),
               sl.at("gpus_per_task"), sl.at("max_parallel"), sl.at("sbatch_args").get<std::vector<std::string>>()};
    s.submissions = j.at("submissions");
  } catch (const nlohmann::json::exception& e) {
    throw_invalid(std::string("not a submission lblight wrote: ") + e.what(), {file.string(), {}, {}});
  }
  return s;
}

void mark_queued(const Submission& s, const std::vector<int>& units, const std::string& job) {
  for (int i : units) {
    const std::string name = s.units.at(static_cast<std::size_t>(i)).name;
    const nlohmann::json state = {{"state", "queued"}, {"job", job + "_" + std::to_string(i)}, {"time", utc_timestamp()}};
    write_file_atomically(state_file(s.out, name), state.dump() + "\n");
  }
}

std::string run_sbatch(const std::vector<std::string>& args) {
  std::vector<std::string> argv_s = {"sbatch", "--parsable"};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  int fds[2];
  if (::pipe(fds) != 0) throw_io(std::string("cannot create a pipe: ") + std::strerror(errno));
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fds[1], 1);
  posix_spawn_file_actions_adddup2(&actions, fds[1], 2);
  posix_spawn_file_actions_addclose(&actions, fds[0]);
  pid_t pid = 0;
  const int spawned = posix_spawnp(&pid, "sbatch", &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  ::close(fds[1]);
  if (spawned != 0) {
    ::close(fds[0]);
    throw Error(ErrorCategory::Unavailable, std::string("cannot run sbatch (") + std::strerror(spawned) +
                                                "): is this a Slurm login node? --dry-run writes the scripts only");
  }
  std::string output;
  char buf[4096];
  ssize_t n = 0;
  while ((n = ::read(fds[0], buf, sizeof buf)) > 0 || (n < 0 && errno == EINTR))
    if (n > 0) output.append(buf, static_cast<std::size_t>(n));
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  while (!output.empty() && std::isspace(static_cast<unsigned char>(output.back()))) output.pop_back();
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw_io("sbatch " + words(args) + " failed: " + (output.empty() ? "no message" : output));
  // --parsable prints "<job id>" or "<job id>;<cluster>", after any warnings.
  const std::string last = output.substr(output.find_last_of('\n') + 1);
  const std::string id = last.substr(0, last.find(';'));
  if (id.empty() || !std::all_of(id.begin(), id.end(), ::isdigit))
    throw_io("sbatch " + words(args) + " printed no job id: " + output);
  return id;
}

std::vector<UnitStatus> submission_status(const Submission& s) {
  std::vector<UnitStatus> out;
  for (const UnitEstimate& u : s.units) {
    UnitStatus st{u.name, "missing", ""};
    const fs::path part = part_dir(s.out, u.name);
    // Checksums read every file whole: a unit whose .vdb changed after it finished (same size) is
    // damaged, not done, so --resume redoes it instead of leaving merge to fail.
    const PartCheck c = check_part(part, u.name, u.hash, /*verify_checksums=*/true);
    std::error_code ec;
    nlohmann::json state;
    if (fs::exists(state_file(s.out, u.name), ec)) {
      try {
        state = read_json(state_file(s.out, u.name), "state file");
      } catch (const Error& e) {
        state = {{"state", "missing"}, {"note", std::string("unreadable state file: ") + e.what()}};
      }
    }
    const std::string recorded = text_of(state, "state");
    if (c.state == PartState::Done) {
      st.state = "done";
      st.detail = part.string() + " (inputs hash " + u.hash + ")";
    } else if (recorded == "running" || recorded == "queued" || recorded == "failed") {
      st.state = recorded;
      st.detail = "job " + text_of(state, "job");
      if (!text_of(state, "host").empty()) st.detail += " on " + text_of(state, "host");
      st.detail += (recorded == "queued" ? ", submitted " : ", since ") + text_of(state, "time");
      if (recorded == "failed") st.detail = "exit code " + state.value("exit_code", nlohmann::json()).dump() + ", " + st.detail;
      if (!text_of(state, "log").empty()) st.detail += "; log " + text_of(state, "log");
    } else {
      st.detail = c.state == PartState::Absent ? "no partial output yet" : part.string() + ": " + c.why;
      if (!text_of(state, "note").empty()) st.detail += "; " + text_of(state, "note");
    }
    out.push_back(st);
  }
  return out;
}

std::string merged_status(const Submission& s) {
  const fs::path dir = merged_dir(s.out);
  std::error_code ec;
  if (!fs::exists(dir, ec)) return "";
  try {
    const nlohmann::json m = read_manifest(dir);
    if (m.value("scene", nlohmann::json::object()).value("hash", "") != s.scene_hash)
      return dir.string() + " holds a bake of another scene (" + m["scene"].value("hash", "no hash") + ")";
    return dir.string() + " (" + std::to_string(m["models"].size()) + " model(s), merged " +
           m.value("created", std::string("?")) + ")";
  } catch (const Error& e) {
    return dir.string() + " is not a finished bake: " + e.what();
  }
}

}  // namespace lblight
