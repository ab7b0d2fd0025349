#include "lblight/io/output_dir.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lblight/core/error.h"
#include "lblight/core/input_file.h"
#include "lblight/core/json_depth.h"
#include "lblight/io/run_paths.h"

namespace fs = std::filesystem;

namespace lblight {

namespace {
std::string unique_suffix() {
  static std::atomic<int> counter{0};
  return std::to_string(::getpid()) + "-" + std::to_string(counter++);
}

// Entries of `dir` named <prefix><pid>-... whose process no longer exists: what an lblight killed
// while writing left behind (staging folders, temporary files). A pid that is alive, or that we
// may not signal, is left alone.
void remove_dead_leftovers(const fs::path& dir, const std::string& prefix) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string rest = name.substr(prefix.size());
    const std::size_t dash = rest.find('-');
    if (dash == 0 || dash == std::string::npos || rest.find_first_not_of("0123456789") != dash) continue;
    const long pid = std::strtol(rest.substr(0, dash).c_str(), nullptr, 10);
    if (pid <= 0 || pid == ::getpid() || ::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;
    std::error_code ignore;
    fs::remove_all(e.path(), ignore);
  }
}

struct KindRules {
  const char* marker;                      // the file that says what wrote the folder
  std::vector<const char*> marker_keys;    // members that file's JSON object must have
  std::vector<const char*> other_files;    // exact names, or ".ext" for any file ending so
  const char* what;
};

KindRules rules(OutputKind kind) {
  if (kind == OutputKind::Bake)
    return {"manifest.json", {"lblight_version", "models"}, {".vdb", ".lbh", ".totals"}, "an lblight bake output"};
  if (kind == OutputKind::Simulation)
    return {"simulation.json", {"lblight_version", "frames"}, {".vdb", ".lbh", "manifest.json"}, "an lblight simulation"};
  return {"report.json", {"curves", "references"}, {"report.csv", ".svg"}, "an lblight report"};
}

bool marker_matches(const fs::path& file, const KindRules& r) {
  std::string text;
  try {
    text = read_input_file(file, "marker file", 64ull << 20);  // never a FIFO or a device
  } catch (const Error&) {
    return false;
  }
  if (json_nesting_depth(text) > 64) return false;  // lblight's markers nest a few levels
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!j.is_object()) return false;
  for (const char* k : r.marker_keys)
    if (!j.contains(k)) return false;
  return true;
}

bool allowed_beside_marker(const fs::directory_entry& e, const KindRules& r) {
  std::error_code ec;
  if (!e.is_regular_file(ec) || e.is_symlink(ec)) return false;
  const std::string name = e.path().filename().string();
  if (name == r.marker) return true;
  for (const char* f : r.other_files) {
    const std::string pat = f;
    if (pat.front() == '.' ? e.path().extension() == pat : name == pat) return true;
  }
  return false;
}

}  // namespace

fs::path output_folder_path(const fs::path& given) {
  fs::path p = given.lexically_normal();
  if (!p.empty() && p.filename().empty()) p = p.parent_path();  // "out/" -> "out"
  const std::string leaf = p.filename().string();
  if (p.empty() || leaf.empty() || leaf == "." || leaf == ".." || p == p.root_path())
    throw_invalid("output path '" + given.string() + "' names no folder to create or replace; allowed: a folder name, "
                  "e.g. out/tree-bake",
                  {given.string(), {}, {}});
  return p;
}

void StagedDirectory::check_target(const fs::path& given, OutputKind kind) {
  const fs::path target = output_folder_path(given);
  std::error_code ec;
  if (!fs::exists(target, ec)) return;
  if (!fs::is_directory(target, ec))
    throw_invalid("output path exists and is not a directory; choose another -o", {target.string(), {}, {}});
  if (fs::is_empty(target, ec)) return;
  const KindRules r = rules(kind);
  if (!marker_matches(target / r.marker, r))
    throw_invalid(std::string("output directory exists, is not empty and is not ") + r.what + " (no " + r.marker +
                      " written by lblight); refusing to replace it: choose another -o or remove it",
                  {target.string(), {}, {}});
  for (const auto& e : fs::directory_iterator(target, ec))
    if (!allowed_beside_marker(e, r))
      throw_invalid(std::string("output directory holds ") + r.what + " and also '" + e.path().filename().string() +
                        "', which lblight did not write; replacing the folder would delete it: move it or choose "
                        "another -o",
                    {target.string(), {}, {}});
  if (ec) throw_io("cannot list the output directory: " + ec.message(), {target.string(), {}, {}});
}

StagedDirectory::StagedDirectory(fs::path target, OutputKind kind) : target_(output_folder_path(target)) {
  check_target(target_, kind);
  const fs::path abs = fs::absolute(target_).lexically_normal();
  const fs::path parent = abs.parent_path();
  std::error_code ec;
  fs::create_directories(parent, ec);
  if (ec) throw_io("cannot create the output's parent folder: " + ec.message(), {parent.string(), {}, {}});
  const std::string leaf = abs.filename().string();
  remove_dead_leftovers(parent, "." + leaf + ".staging-");
  remove_dead_leftovers(parent, ".." + leaf + ".staging-");  // a previous output moved aside by commit()
  staging_ = parent / ("." + leaf + ".staging-" + unique_suffix());
  fs::create_directory(staging_, ec);
  if (ec) throw_io("cannot create staging folder: " + ec.message(), {staging_.string(), {}, {}});
}

StagedDirectory::~StagedDirectory() {
  if (committed_) return;
  std::error_code ec;
  fs::remove_all(staging_, ec);
}

void StagedDirectory::commit() {
  std::error_code ec;
  fs::path old;
  if (fs::exists(target_, ec)) {
    old = staging_.parent_path() / ("." + staging_.filename().string() + ".old");
    fs::rename(target_, old, ec);
    if (ec) throw_io("cannot move the previous output aside: " + ec.message(), {target_.string(), {}, {}});
  }
  fs::rename(staging_, target_, ec);
  if (ec) {
    std::error_code ignore;
    if (!old.empty()) fs::rename(old, target_, ignore);
    throw_io("cannot move the finished output into place: " + ec.message(), {target_.string(), {}, {}});
  }
  committed_ = true;
  if (!old.empty()) fs::remove_all(old, ec);
}

void write_file_atomically(const fs::path& given, const std::function<void(const fs::path& temporary)>& write) {
  std::error_code sec;
  const fs::file_status st = fs::status(given, sec);  // through symlinks
  // Never written through a FIFO (blocks until a reader comes) or a device, nor renamed over one
  // (as root, /dev/null itself): commands check their outputs up front (RunPaths), this is the last
  // line.
  check_output_file_path(given, "output");
  // A symlink to a file: the file it names is replaced, the link stays.
  const fs::path file = fs::is_symlink(fs::symlink_status(given, sec)) && fs::exists(st) ? fs::canonical(given, sec) : given;
  remove_dead_leftovers(file.parent_path().empty() ? fs::path(".") : file.parent_path(),
                        "." + file.filename().string() + ".tmp-");
  const fs::path tmp = file.parent_path() / ("." + file.filename().string() + ".tmp-" + unique_suffix());
  const auto remove_tmp = [&] {
    std::error_code ignore;
    fs::remove(tmp, ignore);
  };
  try {
    write(tmp);
  } catch (...) {
    remove_tmp();
    throw;
  }
  std::error_code ec;
  fs::rename(tmp, file, ec);
  if (ec) {
    remove_tmp();
    throw_io("cannot rename into place: " + ec.message(), {file.string(), {}, {}});
  }
}

void write_file_atomically(const fs::path& file, const std::string& text) {
  write_file_atomically(file, [&](const fs::path& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) throw_io(std::string("cannot create file: ") + std::strerror(errno), {file.string(), {}, {}});
    out << text;
    out.flush();
    if (!out) throw_io("cannot write file (disk full?)", {file.string(), {}, {}});
  });
}

}  // namespace lblight
