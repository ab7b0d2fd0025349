// Output directories appear complete or not at all: everything is written into a hidden
// sibling staging folder, which replaces the target only on commit(). A failed or interrupted
// run leaves the target untouched and removes the staging folder.
#pragma once

#include <filesystem>

namespace lblight {

class StagedDirectory {
 public:
  // Checks that `target` may be (re)placed: it must not exist, be empty, or hold a previous
  // lblight output (manifest.json). Throws Error(InvalidInput) otherwise.
  static void check_target(const std::filesystem::path& target);

  explicit StagedDirectory(std::filesystem::path target);
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

// Writes `text` to `file` through a temporary name in the same folder and a rename.
void write_file_atomically(const std::filesystem::path& file, const std::string& text);

}  // namespace lblight
