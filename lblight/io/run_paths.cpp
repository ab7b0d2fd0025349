#include "lblight/io/run_paths.h"

#include <unistd.h>

#include <algorithm>

#include "lblight/core/error.h"

namespace fs = std::filesystem;

namespace lblight {
namespace {

// What stands at `path` when it is not a regular file or nothing: "a FIFO", "a folder", ...
std::string non_file_kind(const fs::path& path) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);  // through symlinks
  switch (st.type()) {
    case fs::file_type::not_found:
    case fs::file_type::none:
    case fs::file_type::regular: return "";
    case fs::file_type::directory: return "a folder";
    case fs::file_type::fifo: return "a FIFO (named pipe)";
    case fs::file_type::character: return "a character device";
    case fs::file_type::block: return "a block device";
    case fs::file_type::socket: return "a socket";
    default: return ec ? "" : "not a regular file";
  }
}

// The path as the file system resolves it (symlinks in the existing part followed), for
// comparing paths given in different spellings ("a/../b", "./b", a link to b).
fs::path resolved(const fs::path& p) {
  std::error_code ec;
  fs::path r = fs::weakly_canonical(fs::absolute(p, ec), ec);
  return ec ? fs::absolute(p).lexically_normal() : r;
}

// `inner` is `outer` or lies inside it (both resolved).
bool inside(const fs::path& inner, const fs::path& outer) {
  const fs::path rel = inner.lexically_relative(outer);
  return !rel.empty() && *rel.begin() != "..";
}

bool same_file(const fs::path& a, const fs::path& b) {
  if (resolved(a) == resolved(b)) return true;
  std::error_code ec;
  return fs::exists(a, ec) && fs::exists(b, ec) && fs::equivalent(a, b, ec);  // hard links
}

bool is_folder(const fs::path& p, bool declared) {
  std::error_code ec;
  return declared || fs::is_directory(p, ec);
}

std::string named(const std::string& role, const fs::path& p) { return role + " '" + p.string() + "'"; }

// The folder an output goes into: a folder this user may write. A file is written into a folder
// that exists; an output folder's missing parents are created (their nearest existing ancestor
// must be writable).
void check_parent_writable(const fs::path& path, const std::string& role, bool create_parents) {
  fs::path dir = fs::absolute(path).lexically_normal().parent_path();
  std::error_code ec;
  if (!create_parents && !fs::exists(dir, ec))
    throw_invalid(named(role, path) + ": the folder to write into, '" + dir.string() +
                      "', does not exist; allowed: a file in an existing folder",
                  {path.string(), {}, {}});
  while (!dir.empty() && !fs::exists(dir, ec) && dir != dir.root_path()) dir = dir.parent_path();
  if (dir.empty()) return;
  if (!fs::is_directory(dir, ec))
    throw_invalid(named(role, path) + " lies under '" + dir.string() +
                      "', which is a file, not a folder; allowed: a path whose folders exist or can be created",
                  {path.string(), {}, {}});
  if (::access(dir.c_str(), W_OK | X_OK) != 0)
    throw_invalid(named(role, path) + ": this user may not write in folder '" + dir.string() +
                      "'; allowed: a path in a writable folder",
                  {path.string(), {}, {}});
}

}  // namespace

void check_output_file_path(const fs::path& path, const std::string& role) {
  const std::string kind = non_file_kind(path);
  if (!kind.empty())
    throw_invalid(named(role, path) + " is " + kind + "; allowed: a regular file (replaced) or a new file name",
                  {path.string(), {}, {}});
  check_parent_writable(path, role, /*create_parents=*/false);
}

RunPaths& RunPaths::input(const fs::path& path, std::string role) {
  if (!path.empty()) inputs_.push_back({path, std::move(role), false});
  return *this;
}

RunPaths& RunPaths::output_file(const fs::path& path, std::string role) {
  outputs_.push_back({path, std::move(role), false});
  return *this;
}

RunPaths& RunPaths::output_folder(const fs::path& path, std::string role) {
  outputs_.push_back({path, std::move(role), true});
  return *this;
}

void RunPaths::check() const {
  for (std::size_t k = 0; k < outputs_.size(); ++k) {
    const Entry& out = outputs_[k];
    const Location where{out.path.string(), {}, {}};
    if (out.folder) {
      const std::string kind = non_file_kind(out.path);
      if (!kind.empty() && kind != "a folder")
        throw_invalid(named(out.role, out.path) + " is " + kind + "; allowed: a folder (new, empty or a previous "
                      "output of this command)", where);
      std::error_code ec;
      if (fs::exists(out.path, ec) && !fs::is_directory(out.path, ec))
        throw_invalid(named(out.role, out.path) + " is a file; allowed: a folder (new, empty or a previous output "
                      "of this command)", where);
      check_parent_writable(out.path, out.role, /*create_parents=*/true);
    } else {
      check_output_file_path(out.path, out.role);
    }
    const fs::path o = resolved(out.path);
    for (const Entry& in : inputs_) {
      const fs::path i = resolved(in.path);
      if (same_file(out.path, in.path))
        throw_invalid(named(out.role, out.path) + " is also " + named(in.role, in.path) +
                          " of this run, which writing it would replace; allowed: an output path that no input uses",
                      where);
      if (is_folder(in.path, in.folder) && inside(o, i))
        throw_invalid(named(out.role, out.path) + " lies inside " + named(in.role, in.path) +
                          ", which this run reads; allowed: a path outside it",
                      where);
      if (out.folder && inside(i, o))
        throw_invalid(named(out.role, out.path) + " holds " + named(in.role, in.path) +
                          " of this run; replacing the folder would delete it: allowed: a folder outside the inputs",
                      where);
    }
    for (std::size_t m = k + 1; m < outputs_.size(); ++m) {
      const Entry& other = outputs_[m];
      const fs::path p = resolved(other.path);
      if (same_file(out.path, other.path) || (out.folder && inside(p, o)) || (other.folder && inside(o, p)))
        throw_invalid(named(out.role, out.path) + " and " + named(other.role, other.path) +
                          " would be written to the same place; allowed: two separate paths",
                      where);
    }
  }
}

}  // namespace lblight
