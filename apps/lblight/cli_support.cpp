#include "apps/lblight/cli_support.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <thread>

#include <unistd.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "lblight/core/error.h"
#include "lblight/io/run_paths.h"

namespace lblight::cli {

std::atomic<bool> g_interrupted{false};

namespace {
// After a signal, long work stops at its next check of g_interrupted and cleans up; should it
// not come back within this many seconds (stuck in a library call), the process ends anyway.
constexpr unsigned kStopGraceSeconds = 60;

extern "C" void on_stop_overdue(int) {
  static const char msg[] = "lblight: did not stop within 60 s of the signal; exiting now\n";
  ssize_t ignored = ::write(2, msg, sizeof msg - 1);
  (void)ignored;
  ::_exit(130);
}

extern "C" void on_signal(int sig) {
  const bool first = !g_interrupted.exchange(true);
  // A second INT/TERM/HUP ends the process at once. A broken pipe (stdout's reader gone) would
  // raise SIGPIPE again on the next write, before the output is cleaned up: ignore it from now on.
  std::signal(sig, sig == SIGPIPE ? SIG_IGN : SIG_DFL);
  if (first && sig != SIGPIPE) ::alarm(kStopGraceSeconds);
}
}  // namespace

void install_signal_handlers() {
  for (int sig : {SIGINT, SIGTERM, SIGHUP, SIGPIPE}) std::signal(sig, on_signal);
  std::signal(SIGALRM, on_stop_overdue);
}

void throw_if_interrupted() { throw_if_cancelled(&g_interrupted); }

int usable_threads(int requested) {
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  if (requested <= 4 * cores) return requested;
  spdlog::warn("--threads {} on {} core(s): using {}", requested, cores, 4 * cores);
  return 4 * cores;
}

CLI::Validator finite_range(double lo, double hi) {
  auto text = [](double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", v);
    return std::string(buf);
  };
  const std::string range = text(lo) + " to " + text(hi);
  return CLI::Validator(
      [lo, hi, range](std::string& s) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(s.c_str(), &end);
        if (end == s.c_str() || *end != '\0') return "'" + s + "' is not a number";
        if (!std::isfinite(v)) return "value " + s + " is not a finite number; allowed: " + range;
        if (v < lo || v > hi) return "value " + s + " is out of range; allowed: " + range;
        return {};
      },
      "FLOAT in " + range);
}

CLI::Validator integer_range(std::uint64_t lo, std::uint64_t hi) {
  const std::string range = std::to_string(lo) + " to " + std::to_string(hi);
  return CLI::Validator(
      [lo, hi, range](std::string& s) -> std::string {
        std::uint64_t v = 0;
        const char* end = s.data() + s.size();
        const auto r = std::from_chars(s.data(), end, v);
        if (s.empty() || !std::isdigit(static_cast<unsigned char>(s[0])) || r.ptr != end ||
            (r.ec != std::errc() && r.ec != std::errc::result_out_of_range))
          return "'" + s + "' is not a whole number >= 0 in digits; allowed: " + range;
        if (r.ec == std::errc::result_out_of_range || v < lo || v > hi)
          return "value " + s + " is out of range; allowed: " + range;
        return {};
      },
      "UINT in " + range);
}

const CLI::Validator kNonEmpty(
    [](std::string& s) -> std::string {
      return s.empty() ? "the value is empty; give one or leave the option out" : "";
    },
    "");  // no description: --help keeps showing TEXT

void check_output_file(const std::filesystem::path& input, const std::filesystem::path& output,
                       const std::string& extension) {
  if (output.extension() != extension)
    throw_invalid("-o '" + output.string() + "' does not end in " + extension + "; allowed: a " + extension +
                      " file name",
                  {output.string(), {}, {}});
  RunPaths().input(input, "the input").output_file(output, "-o").check();
}

void check_scene_output(const Scene& scene, const std::filesystem::path& folder) {
  RunPaths paths;
  for (const std::filesystem::path& f : scene_input_files(scene)) paths.input(f, "input file");
  paths.output_folder(folder, "-o").check();
}

void setup_logging(int verbosity) {
  auto logger = spdlog::stderr_color_mt("lblight");
  // -v: milliseconds, to read where a short run's time goes from the log alone
  logger->set_pattern(verbosity > 0 ? "[%H:%M:%S.%e] %^%l%$: %v" : "[%H:%M:%S] %^%l%$: %v");
  spdlog::set_default_logger(logger);
  spdlog::set_level(verbosity < 0   ? spdlog::level::warn
                    : verbosity == 0 ? spdlog::level::info
                    : verbosity == 1 ? spdlog::level::debug
                                     : spdlog::level::trace);
}

void keep_freed_host_memory() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, 64 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
}

std::string Table::str() const {
  std::vector<std::size_t> width;
  for (const auto& r : rows_)
    for (std::size_t c = 0; c < r.size(); ++c) {
      if (width.size() <= c) width.push_back(0);
      width[c] = std::max(width[c], r[c].size());
    }
  auto numeric = [](const std::string& s) {
    return !s.empty() && (std::isdigit(static_cast<unsigned char>(s[0])) || s[0] == '-' || s[0] == '(' || s == "n/a");
  };
  std::ostringstream out;
  for (std::size_t i = 0; i < rows_.size(); ++i) {
    const auto& r = rows_[i];
    for (std::size_t c = 0; c < r.size(); ++c) {
      const std::size_t pad = width[c] - r[c].size();
      const bool right = i > 0 && numeric(r[c]);
      if (right) out << std::string(pad, ' ') << r[c];
      else out << r[c] << (c + 1 < r.size() ? std::string(pad, ' ') : "");
      if (c + 1 < r.size()) out << "  ";
    }
    out << "\n";
  }
  return out.str();
}

std::string format_seconds(double s) {
  char buf[32];
  if (s < 10) std::snprintf(buf, sizeof buf, "%.3f", s);
  else std::snprintf(buf, sizeof buf, "%.1f", s);
  return buf;
}

std::string format_error(double e) {
  if (!std::isfinite(e)) return "n/a";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1e", e);
  return buf;
}

std::string format_bytes(double b) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (b >= 1024 && u < 4) {
    b /= 1024;
    ++u;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.2f %s", b, units[u]);
  return buf;
}

std::string format_direction(const std::array<int, 3>& d) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "(%+d,%+d,%+d)", d[0], d[1], d[2]);
  return buf;
}

void parse_iterations(const std::string& text, IterationMode& mode, int& steps) {
  if (text == "auto") {
    mode = IterationMode::Auto;
    return;
  }
  if (text == "paper") {
    mode = IterationMode::Paper;
    return;
  }
  try {
    std::size_t used = 0;
    const long long n = std::stoll(text, &used);
    if (used == text.size() && n >= 1 && n <= 100000000) {
      mode = IterationMode::Fixed;
      steps = static_cast<int>(n);
      return;
    }
  } catch (const std::logic_error&) {
  }
  throw_invalid("--iterations '" + text + "': allowed: auto, paper, or a step count 1..100000000");
}

Precision parse_precision(const std::string& text) {
  if (text == "float32") return Precision::Float32;
  if (text == "float64") return Precision::Float64;
  if (text == "float16") return Precision::Float16;
  throw_invalid("--precision '" + text + "': allowed: float32, float64, float16");
}

std::string command_line(int argc, char** argv) {
  std::string s;
  for (int i = 0; i < argc; ++i) {
    std::string a = argv[i];
    if (a.find_first_of(" \t\"'") != std::string::npos) a = "'" + a + "'";
    s += (i ? " " : "") + a;
  }
  return s;
}

}  // namespace lblight::cli
