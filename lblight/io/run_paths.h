// Every path one command run reads and writes, checked together before any work
// (docs/reliability.md, "Outputs"). A command lists its inputs and outputs, then calls check():
//   - an output file is absent or a regular file (through symlinks): never a folder, FIFO, device
//     or socket (writing into a FIFO blocks until a reader comes; a device is not a result);
//   - an output folder is absent or a folder (what it may hold: StagedDirectory::check_target);
//   - no output is an input of the run, lies inside an input folder (a bake) or holds an input;
//   - no two outputs name the same file or lie one inside the other;
//   - the folder an output file goes into exists (an output folder's parents may be created), and
//     this user may write there.
// Refusals are Error(InvalidInput) naming the option, the path and what is allowed (exit 2).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace lblight {

class RunPaths {
 public:
  // `role` names the path in messages: "-o", "--png", "the scene", "bake folder".
  RunPaths& input(const std::filesystem::path& path, std::string role);
  RunPaths& output_file(const std::filesystem::path& path, std::string role);
  RunPaths& output_folder(const std::filesystem::path& path, std::string role);
  void check() const;

 private:
  struct Entry {
    std::filesystem::path path;
    std::string role;
    bool folder = false;
  };
  std::vector<Entry> inputs_, outputs_;
};

// The file checks of RunPaths for one output file alone: absent or a regular file, its folder
// writable. write_file_atomically calls it too, so no command can write into a FIFO or device.
void check_output_file_path(const std::filesystem::path& path, const std::string& role);

}  // namespace lblight
