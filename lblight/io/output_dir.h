// Output directories appear complete or not at all: everything is written into a hidden
// sibling staging folder, which replaces the target only on commit(). A failed or interrupted
// run leaves the target untouched and removes the staging folder.
#pragma once

#include <filesystem>
#include <functional>
#include <string>

namespace lblight {

// What a command writes into its output directory, so that a later run replaces only that.
enum class OutputKind {
  Bake,    // manifest.json (lblight_version, models) and .vdb/.lbh files (.totals: a unit's share)
  Report,  // report.json (curves, references), report.csv and .svg plots
  Simulation,  // simulation.json (lblight_version, frames), one .vdb per model and frame, and the
               // manifest.json (and .lbh files) of their lighting (simulate --light)
};

// The output folder a user named, as lblight uses it: lexically normal, without a trailing
// separator ("out/" is "out"). Error(InvalidInput) for a path that names no folder to create or
// replace ("", ".", "..", "/", "a/..").
std::filesystem::path output_folder_path(const std::filesystem::path& given);

class StagedDirectory {
 public:
  // Checks that `target` (after output_folder_path) may be (re)placed: it must not exist, be
  // empty, or hold a previous output of the same kind and nothing else (no folders, no other
  // files). Throws Error(InvalidInput) otherwise, naming what is in the way: replacing deletes
  // the folder.
  static void check_target(const std::filesystem::path& target, OutputKind kind);

  // Stages beside `target`; staging folders that dead lblight processes left there (a SIGKILL, a
  // crash) are removed first.
  StagedDirectory(std::filesystem::path target, OutputKind kind);
  StagedDirectory(const StagedDirectory&) = delete;
  StagedDirectory& operator=(const StagedDirectory&) = delete;
  ~StagedDirectory();

  const std::filesystem::path& staging() const { return staging_; }
  const std::filesystem::path& target() const { return target_; }
  std::filesystem::path path(const std::string& name) const { return staging_ / name; }
  void commit();

 private:
  std::filesystem::path target_, staging_;
  bool committed_ = false;
};

// Has `write` fill a temporary file beside `file`, then renames it into place: `file` appears
// complete or not at all. The temporary is removed when `write` throws (its error passes on) or
// the rename fails. Anything but a regular file at `file` (a folder, FIFO, device) is refused
// (Error(InvalidInput), check_output_file_path); a symlink's target file is replaced, not the link.
void write_file_atomically(const std::filesystem::path& file,
                           const std::function<void(const std::filesystem::path& temporary)>& write);
// The same for a file whose content is `text`.
void write_file_atomically(const std::filesystem::path& file, const std::string& text);

}  // namespace lblight
