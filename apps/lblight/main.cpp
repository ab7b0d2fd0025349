// lblight: lattice-Boltzmann lighting precompute. main() wires subcommands and turns the
// library's error categories into exit codes: 0 ok, 2 invalid input, 1 anything else.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "apps/lblight/cli_support.h"
#include "apps/lblight/commands.h"
#include "lblight/core/error.h"
#include "lblight/core/script_text.h"
#include "lblight/core/version.h"

int main(int argc, char** argv) {
  using namespace lblight;
  cli::GlobalOptions global;
  global.command_line = cli::command_line(argc, argv);

  CLI::App app{"lblight " + std::string(kVersion) +
               ": precomputes volumetric lighting for plants, forests and clouds with the lattice-Boltzmann "
               "lighting model (D3Q19). Bakes the 19 base solutions a renderer relights for any sun direction."};
  app.set_version_flag("--version", std::string("lblight ") + kVersion);
  app.require_subcommand(1);
  app.fallthrough();  // global flags (-v, -q) may follow the subcommand
  int verbose = 0;
  bool quiet = false;
  app.add_flag("-v,--verbose", verbose, "More log output on stderr (repeat for trace)");
  app.add_flag("-q,--quiet", quiet, "Only warnings and errors on stderr");
  app.footer("Exit codes: 0 success, 2 invalid input, 1 other failure, 130 interrupted.\n"
             "Run 'lblight <command> --help' for a command's options.");

  const std::vector<cli::Command> commands = {
      cli::add_bake_command(app, global),
      cli::add_validate_command(app, global),
      cli::add_inspect_command(app, global),
      cli::add_bench_command(app, global),
      cli::add_report_command(app, global),
      cli::add_voxelize_command(app, global),
      cli::add_compress_command(app, global),
      cli::add_decompress_command(app, global),
      cli::add_nanovdb_command(app, global),
      cli::add_compare_command(app, global),
      cli::add_truth_command(app, global),
      cli::add_relight_command(app, global),
      cli::add_render_command(app, global),
      cli::add_sun_weights_command(app, global),
      cli::add_schema_command(app, global),
      cli::add_simulate_command(app, global),
      cli::add_merge_command(app, global),
      cli::add_submit_command(app, global),
      cli::add_status_command(app, global),
  };

  // The first word that is not a flag names the command (the global flags take no values); CLI11
  // would only say that a command is required.
  for (int i = 1; i < argc; ++i) {
    const std::string word = argv[i];
    if (word.empty() || word[0] == '-') continue;
    std::string names;
    bool known = false;
    for (const cli::Command& c : commands) {
      names += (names.empty() ? "" : ", ") + c.app->get_name();
      known = known || c.app->get_name() == word;
    }
    if (!known) {
      std::cerr << "error: unknown command '" << printable(word.substr(0, 80)) << "'; allowed: " << names
                << "\nRun 'lblight --help' for what each does.\n";
      return 2;
    }
    break;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {  // --help, --version (CallForHelp derives from Success)
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // CLI11 quotes the offending value: its control characters are shown escaped, line by line.
    std::ostringstream err;
    app.exit(e, std::cout, err);
    std::istringstream lines(err.str());
    for (std::string line; std::getline(lines, line);) std::cerr << printable(line) << "\n";
    return 2;
  }

  global.verbosity = quiet ? -1 : verbose;
  cli::setup_logging(global.verbosity);
  cli::install_signal_handlers();
  try {
    for (const cli::Command& c : commands)
      if (c.app->parsed()) {
        const int rc = c.run();
        // What a command printed must have reached stdout (a full disk, a closed pipe): a result
        // the caller never saw is not a success.
        std::cout.flush();
        if (std::fflush(stdout) != 0 || std::ferror(stdout) || !std::cout) {
          spdlog::error("cannot write to standard output (disk full or pipe closed?): the command's printed result "
                        "is lost");
          return rc == 0 ? 1 : rc;
        }
        return rc;
      }
    return 1;
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return exit_code_for(e.category());
  } catch (const std::bad_alloc&) {
    spdlog::error("out of memory");
    return 1;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}
