// One subcommand per file: each registers its options and returns the function that runs it.
#pragma once

#include <functional>
#include <string>

namespace CLI {
class App;
}

namespace lblight::cli {

struct GlobalOptions {
  int verbosity = 0;
  std::string command_line;
};

struct Command {
  CLI::App* app = nullptr;    // the subcommand, to see whether it was given
  std::function<int()> run;  // runs it after parsing; returns the exit code
};

Command add_bake_command(CLI::App& app, const GlobalOptions& global);
Command add_validate_command(CLI::App& app, const GlobalOptions& global);
Command add_inspect_command(CLI::App& app, const GlobalOptions& global);
Command add_bench_command(CLI::App& app, const GlobalOptions& global);
Command add_report_command(CLI::App& app, const GlobalOptions& global);
Command add_voxelize_command(CLI::App& app, const GlobalOptions& global);
Command add_compress_command(CLI::App& app, const GlobalOptions& global);
Command add_nanovdb_command(CLI::App& app, const GlobalOptions& global);
Command add_decompress_command(CLI::App& app, const GlobalOptions& global);
Command add_compare_command(CLI::App& app, const GlobalOptions& global);
Command add_truth_command(CLI::App& app, const GlobalOptions& global);
Command add_relight_command(CLI::App& app, const GlobalOptions& global);
Command add_render_command(CLI::App& app, const GlobalOptions& global);
Command add_sun_weights_command(CLI::App& app, const GlobalOptions& global);
Command add_schema_command(CLI::App& app, const GlobalOptions& global);
Command add_simulate_command(CLI::App& app, const GlobalOptions& global);
Command add_merge_command(CLI::App& app, const GlobalOptions& global);
Command add_submit_command(CLI::App& app, const GlobalOptions& global);
Command add_status_command(CLI::App& app, const GlobalOptions& global);

}  // namespace lblight::cli
