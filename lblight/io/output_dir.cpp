#include "lblight/io/output_dir.h"

#include <unistd.h>

#include <atomic>
#include <fstream>
#include <string>

#include "lblight/core/error.h"

namespace fs = std::filesystem;

namespace lblight {

namespace {
std::string unique_suffix() {
  static std::atomic<int> counter{0};
  return std::to_string(::getpid()) + "-" + std::to_string(counter++);
}
}  // namespace

void StagedDirectory::check_target(const fs::path& target) {
  std::error_code ec;
  if (!fs::exists(target, ec)) return;
  if (!fs::is_directory(target, ec))
    throw_invalid("output path exists and is not a directory; choose another -o", {target.string(), {}, {}});
  if (fs::is_empty(target, ec) || fs::exists(target / "manifest.json", ec)) return;
  throw_invalid("output directory exists, is not empty and holds no lblight manifest.json; refusing to replace it",
                {target.string(), {}, {}});
}

StagedDirectory::StagedDirectory(fs::path target) : target_(std::move(target)) {
  check_target(target_);
  const fs::path abs = fs::absolute(target_).lexically_normal();
  const fs::path parent = abs.parent_path();
  std::error_code ec;
  fs::create_directories(parent, ec);
  if (ec) throw_io("cannot create the output's parent folder: " + ec.message(), {parent.string(), {}, {}});
  const std::string leaf = abs.filename().empty() ? abs.parent_path().filename().string() : abs.filename().string();
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

void write_file_atomically(const fs::path& file, const std::string& text) {
  const fs::path tmp = file.parent_path() / ("." + file.filename().string() + ".tmp-" + unique_suffix());
  {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) throw_io("cannot create file", {tmp.string(), {}, {}});
    out << text;
    out.flush();
    if (!out) {
      std::error_code ec;
      fs::remove(tmp, ec);
      throw_io("cannot write file (disk full?)", {tmp.string(), {}, {}});
    }
  }
  std::error_code ec;
  fs::rename(tmp, file, ec);
  if (ec) {
    std::error_code ignore;
    fs::remove(tmp, ignore);
    throw_io("cannot rename into place: " + ec.message(), {file.string(), {}, {}});
  }
}

}  // namespace lblight
