#include "lblight/core/error.h"

#include <sstream>

namespace lblight {

namespace {
std::string compose(const std::string& message, const Location& where) {
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
      message_(message) {}

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
