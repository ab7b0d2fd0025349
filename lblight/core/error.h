// The library's single error type. Only main() turns categories into exit codes.
#pragma once

#include <atomic>
#include <stdexcept>
#include <string>

namespace lblight {

enum class ErrorCategory {
  InvalidInput,  // the user's scene, grid or options are wrong: exit code 2
  Io,            // a file could not be read or written: exit code 1
  Unavailable,   // a requested backend or device is not present: exit code 1
  Cancelled,     // interrupted by a signal: exit code 130
  Internal,      // anything else: exit code 1
};

// Where an input error sits: a file, a JSON pointer inside it, and/or a voxel.
struct Location {
  std::string file;
  std::string json_path;  // RFC 6901 pointer, e.g. /models/0/material/sigma_a/1
  std::string voxel;      // "(i, j, k)" in grid index space, when a grid value is at fault
  bool empty() const { return file.empty() && json_path.empty() && voxel.empty(); }
};

class Error : public std::runtime_error {
 public:
  Error(ErrorCategory category, const std::string& message, Location where = {});

  ErrorCategory category() const { return category_; }
  const Location& where() const { return where_; }
  const std::string& message() const { return message_; }

 private:
  ErrorCategory category_;
  Location where_;
  std::string message_;
};

// Shorthands for the common cases.
[[noreturn]] void throw_invalid(const std::string& message, Location where = {});
[[noreturn]] void throw_io(const std::string& message, Location where = {});
// Error(Cancelled) once *cancel is set (a signal arrived); a null flag never cancels.
void throw_if_cancelled(const std::atomic<bool>* cancel);

// A number for a message: 6 significant digits, as a user would write it (2e-05, 0.125, 1e+30).
std::string message_number(double v);

int exit_code_for(ErrorCategory category);

}  // namespace lblight
