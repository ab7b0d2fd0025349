#include "lblight/core/input_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace lblight {
namespace {

Location at_file(const std::filesystem::path& file, Location where) {
  if (where.file.empty()) where.file = file.string();
  return where;
}

std::string kind_of(mode_t mode) {
  if (S_ISDIR(mode)) return "a folder";
  if (S_ISFIFO(mode)) return "a pipe (FIFO)";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

[[noreturn]] void not_regular(const std::filesystem::path& file, const std::string& what, mode_t mode,
                              const Location& where) {
  throw_invalid(what + " " + file.string() + " is " + kind_of(mode) + "; allowed: a regular file",
                at_file(file, where));
}

}  // namespace

std::uint64_t check_regular_file(const std::filesystem::path& file, const std::string& what, Location where) {
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0) {
    if (errno == ENOENT || errno == ENOTDIR) throw_invalid(what + " " + file.string() + " does not exist", at_file(file, where));
    throw_io("cannot read " + what + " " + file.string() + ": " + std::strerror(errno), at_file(file, where));
  }
  if (!S_ISREG(st.st_mode)) not_regular(file, what, st.st_mode, where);
  return static_cast<std::uint64_t>(st.st_size);
}

std::string read_input_file(const std::filesystem::path& file, const std::string& what, std::uint64_t max_bytes,
                            Location where) {
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer before fstat can
  // tell what it is.
  const int fd = ::open(file.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT || errno == ENOTDIR) throw_invalid(what + " " + file.string() + " does not exist", at_file(file, where));
    throw_io("cannot read " + what + " " + file.string() + ": " + std::strerror(errno), at_file(file, where));
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0) throw_io("cannot read " + what + " " + file.string() + ": " + std::strerror(errno), at_file(file, where));
  if (!S_ISREG(st.st_mode)) not_regular(file, what, st.st_mode, where);
  const auto size = static_cast<std::uint64_t>(st.st_size);
  if (size > max_bytes)
    throw_invalid(what + " " + file.string() + " has " + std::to_string(size) + " bytes; allowed: at most " +
                      std::to_string(max_bytes),
                  at_file(file, where));
  std::string text(static_cast<std::size_t>(size), '\0');
  std::size_t got = 0;
  while (got < text.size()) {  // never past the size stat gave: a file growing meanwhile is cut there
    const ssize_t n = ::read(fd, &text[got], text.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw_io("cannot read " + what + " " + file.string() + ": " + std::strerror(errno), at_file(file, where));
    if (n == 0) break;  // shrank meanwhile
    got += static_cast<std::size_t>(n);
  }
  text.resize(got);
  return text;
}

}  // namespace lblight
