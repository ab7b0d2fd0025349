// Small helpers shared by the subcommands: logging, interruption, tables, option parsing.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "lblight/backend/backend.h"
#include "lblight/scene/scene.h"

namespace lblight::cli {

// Set by SIGINT, SIGTERM, SIGHUP (terminal closed) and SIGPIPE (stdout's reader gone);
// long-running commands poll it and stop cleanly, removing what they had started to write.
extern std::atomic<bool> g_interrupted;
void install_signal_handlers();
// Throws Error(Cancelled) once a signal came: commands call it before putting output in place.
void throw_if_interrupted();

void setup_logging(int verbosity);  // -1 quiet, 0 normal, 1 verbose, 2 trace
// Keeps memory the process frees for its next allocations instead of returning it to the system
// (glibc: no mmap below 64 MiB, no trimming below 1 GiB free). For a host that waits on a GPU:
// each batch's totals (tens of MB) otherwise arrive in fresh pages, and their first-touch faults
// were a tenth of the plant-128 bake on an H200's virtual machine (docs/performance.md).
void keep_freed_host_memory();

// Plain-text table with right-aligned numeric columns.
class Table {
 public:
  explicit Table(std::vector<std::string> header) : rows_{std::move(header)} {}
  void add(std::vector<std::string> row) { rows_.push_back(std::move(row)); }
  std::string str() const;

 private:
  std::vector<std::vector<std::string>> rows_;
};

std::string format_seconds(double s);
std::string format_error(double e);      // "3.2e-05", or "n/a" when not estimable
std::string format_bytes(double bytes);  // "1.23 GiB"
std::string format_direction(const std::array<int, 3>& d);

// A number option's check: finite and within [lo, hi] (CLI::Range lets NaN through, since every
// comparison with NaN is false).
CLI::Validator finite_range(double lo, double hi);

// A whole-number option's check on its text, before CLI11 converts it: decimal digits only (no
// sign, so "-1" cannot wrap to 2^64 - 1 in an unsigned field), no overflow, within [lo, hi].
CLI::Validator integer_range(std::uint64_t lo, std::uint64_t hi);

// A text option's check: not empty. An empty value (a shell variable that was never set) would
// otherwise fall back to the default silently, writing somewhere the user did not name.
extern const CLI::Validator kNonEmpty;

// An output file name given to a command that writes one file from one input: it must end in
// `extension` (".vdb") and pass RunPaths (a regular file or new, not `input` nor inside it, in a
// writable folder). Error(InvalidInput) naming `output` otherwise.
void check_output_file(const std::filesystem::path& input, const std::filesystem::path& output,
                       const std::string& extension);
// An output folder of a run that reads `scene`: RunPaths over the scene's files and the folder.
void check_scene_output(const Scene& scene, const std::filesystem::path& folder);

// "--iterations paper|auto|N"
void parse_iterations(const std::string& text, IterationMode& mode, int& steps);
Precision parse_precision(const std::string& text);

std::string command_line(int argc, char** argv);

// A --threads value as it will be used: more than 4 per core buys nothing and can exceed what the
// system lets a process start (the OpenMP runtime then aborts, mid-bake): clamped, with a warning.
int usable_threads(int requested);

}  // namespace lblight::cli
