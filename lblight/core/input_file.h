// Input files are read only when they are regular files: a FIFO, a device (/dev/zero) or a folder
// is refused before anything waits on it or reads it without end, and a file is never read past
// the size stat reported for it (docs/reliability.md).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "lblight/core/error.h"

namespace lblight {

// Throws Error(InvalidInput) at `where` (the file when `where` names none) unless `file` exists
// and is a regular file (after following symlinks); `what` says what it was meant to be ("scene
// file", "mesh file"). Returns its size in bytes.
std::uint64_t check_regular_file(const std::filesystem::path& file, const std::string& what, Location where = {});

// The whole of a regular file, at most max_bytes (Error(InvalidInput) naming the file when it is
// larger), read without blocking on anything that is not a regular file. Error(Io) when the file
// exists but cannot be read.
std::string read_input_file(const std::filesystem::path& file, const std::string& what, std::uint64_t max_bytes,
                            Location where = {});

}  // namespace lblight
