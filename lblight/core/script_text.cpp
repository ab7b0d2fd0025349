#include "lblight/core/script_text.h"

#include <algorithm>
#include <cstdio>
#include <cstring>

#include "lblight/core/error.h"

namespace lblight {
namespace {

bool is_control(char c) { return static_cast<unsigned char>(c) < 0x20 || c == 0x7f; }

bool needs_no_quotes(const std::string& value) {
  return !value.empty() && std::all_of(value.begin(), value.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || std::strchr("_-./:=,+%@", c);
  });
}

}  // namespace

int first_control_character(std::string_view text) {
  for (char c : text)
    if (is_control(c)) return static_cast<unsigned char>(c);
  return -1;
}

std::string printable(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    if (!is_control(c)) {
      out += c;
    } else if (c == '\n') {
      out += "\\n";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c == '\r') {
      out += "\\r";
    } else {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", static_cast<unsigned char>(c));
      out += buf;
    }
  }
  return out;
}

void check_script_value(const std::string& value, const std::string& what) {
  const int c = first_control_character(value);
  if (c < 0) return;
  char code[8];
  std::snprintf(code, sizeof code, "0x%02x", c);
  throw_invalid(what + " '" + printable(value) + "' holds a control character (" + code +
                    "), which would break the generated script; allowed: printable text (spaces and quotes are "
                    "quoted)",
                {what, {}, {}});
}

std::string shell_word(const std::string& value) {
  if (needs_no_quotes(value)) return value;
  std::string q = "'";
  for (char c : value) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string sbatch_word(const std::string& value) {
  if (needs_no_quotes(value)) return value;
  std::string q = "\"";
  for (char c : value) {
    if (c == '"' || c == '\\') q += '\\';
    q += c;
  }
  return q + "\"";
}

}  // namespace lblight
