#include "lblight/core/error.h"

#include <sstream>

#include "lblight/core/script_text.h"

namespace lblight {

namespace {
// A message quotes input (names, paths, values); hostile input can make that megabytes. Each part
// is cut to a size a terminal and a log can take, saying how much was left out.
constexpr std::size_t kMaxPart = 2000;
// Control characters of echoed input (a newline, an escape sequence) are shown escaped, never sent
// to the terminal as they are.
std::string bounded(const std::string& raw) {
  const std::string s = printable(raw);
  if (s.size() <= kMaxPart) return s;
  return s.substr(0, kMaxPart) + "... (" + std::to_string(s.size() - kMaxPart) + " more characters)";
}

std::string compose(const std::string& raw_message, const Location& raw_where) {
  const std::string message = bounded(raw_message);
  Location where{bounded(raw_where.file), bounded(raw_where.json_path), bounded(raw_where.voxel)};
  std::string text;
  if (!where.file.empty()) text += where.file;
  if (!where.json_path.empty()) text += (text.empty() ? "" : ": ") + where.json_path;
  if (!where.voxel.empty()) text += (text.empty() ? "voxel " : " voxel ") + where.voxel;
  if (!text.empty()) text += ": ";
  return text + message;
}
}  // namespace

Error::Error(ErrorCategory category, const std::string& message, Location where)
    : std::runtime_error(compose(message, where)),
      category_(category),
      where_(std::move(where)),
      message_(bounded(message)) {}

void throw_invalid(const std::string& message, Location where) {
  throw Error(ErrorCategory::InvalidInput, message, std::move(where));
}

void throw_io(const std::string& message, Location where) {
  throw Error(ErrorCategory::Io, message, std::move(where));
}

int exit_code_for(ErrorCategory category) {
  switch (category) {
    case ErrorCategory::InvalidInput: return 2;
    case ErrorCategory::Cancelled: return 130;
    default: return 1;
  }
}

void throw_if_cancelled(const std::atomic<bool>* cancel) {
  if (cancel && cancel->load()) throw Error(ErrorCategory::Cancelled, "interrupted");
}

std::string message_number(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

}  // namespace lblight
