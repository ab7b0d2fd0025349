// lblight status: which units of a submission are done, running, queued, failed or missing, from
// what the jobs left in its folder (not from Slurm's accounting, which a cluster may not keep).
#include <CLI/CLI.hpp>

#include <filesystem>
#include <iostream>
#include <map>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/pipeline/slurm.h"

namespace fs = std::filesystem;

namespace lblight::cli {
namespace {

struct StatusArgs {
  std::string folder;
  bool json = false;
};

int run_status(const StatusArgs& a) {
  const Submission s = read_submission(a.folder);
  const std::vector<UnitStatus> units = submission_status(s);
  const std::string merged = merged_status(s);
  std::map<std::string, int> count;
  for (const UnitStatus& u : units) ++count[u.state];
  if (a.json) {
    nlohmann::json j;
    j["scene"] = {{"file", s.scene_file.string()}, {"name", s.scene_name}, {"hash", s.scene_hash}};
    j["units"] = nlohmann::json::array();
    for (const UnitStatus& u : units) j["units"].push_back({{"name", u.name}, {"state", u.state}, {"detail", u.detail}});
    j["counts"] = count;
    j["merged"] = merged.empty() ? nlohmann::json(nullptr) : nlohmann::json(merged);
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  std::cout << "scene '" << s.scene_name << "' (" << s.scene_file.string() << ", " << s.scene_hash << "), "
            << units.size() << " unit(s) on " << s.backend << "\n";
  Table table({"unit", "state", "detail"});
  for (const UnitStatus& u : units) table.add({u.name, u.state, u.detail});
  std::cout << table.str();
  std::string line;
  for (const char* state : {"done", "running", "queued", "failed", "missing"})
    line += (line.empty() ? "" : ", ") + std::to_string(count[state]) + " " + state;
  std::cout << line << "\nmerged: " << (merged.empty() ? "no" : merged) << "\n";
  if (count["failed"] > 0 || (count["missing"] > 0 && count["running"] + count["queued"] == 0))
    std::cout << "a failed or missing unit cancels the merge: see its log, fix the cause, then run lblight submit "
              << s.scene_file.string() << " --slurm --resume -o " << s.out.string() << " (with the same options)\n";
  return 0;
}

}  // namespace

Command add_status_command(CLI::App& app, const GlobalOptions&) {
  auto args = std::make_shared<StatusArgs>();
  CLI::App* cmd = app.add_subcommand(
      "status",
      "Show which work units of an `lblight submit` folder are done (a finished partial output with the "
      "submitted inputs hash; files checked by size), running, queued or failed (the state its job "
      "left, with exit code and log), or missing, and whether the merged bake is there. Reads the folder only, "
      "not Slurm's accounting.");
  cmd->add_option("folder", args->folder, "The submission folder (lblight submit -o)")->required()->check(kNonEmpty);
  cmd->add_flag("--json", args->json, "Print JSON instead of a table");
  return {cmd, [args] { return run_status(*args); }};
}

}  // namespace lblight::cli
