// Path-aware access to a parsed JSON document: every failure names the file, the JSON pointer,
// the value found and what is allowed. Internal to the scene parser.
#pragma once

#include <initializer_list>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lblight/core/error.h"

namespace lblight {

class JsonReader {
 public:
  JsonReader(const nlohmann::json& j, std::string path, std::string file)
      : j_(&j), path_(std::move(path)), file_(std::move(file)) {}

  const nlohmann::json& json() const { return *j_; }
  const std::string& path() const { return path_; }
  const std::string& file() const { return file_; }
  std::string path_of(const std::string& key) const { return path_ + "/" + key; }
  Location location(const std::string& key = {}) const {
    return {file_, key.empty() ? (path_.empty() ? "/" : path_) : path_of(key), {}};
  }

  bool has(const std::string& key) const { return j_->is_object() && j_->contains(key); }
  JsonReader child(const std::string& key) const;       // required member
  JsonReader element(std::size_t index) const;           // array element
  void expect_object() const;

  std::string string(const std::string& key) const;                         // required
  std::string string_or(const std::string& key, const std::string& fallback) const;
  double number(const std::string& key, double lo, double hi, const std::string& allowed) const;
  double number_or(const std::string& key, double fallback, double lo, double hi, const std::string& allowed) const;
  long long integer_or(const std::string& key, long long fallback, long long lo, long long hi) const;
  bool boolean_or(const std::string& key, bool fallback) const;

  // This node itself as a finite number within [lo, hi].
  double as_number(double lo, double hi, const std::string& allowed) const;
  // This node as a list of exactly `count` such numbers; `shape` names them in the message
  // ("[x, y, z]").
  std::vector<double> as_numbers(std::size_t count, const std::string& shape, double lo, double hi,
                                 const std::string& allowed) const;

  [[noreturn]] void fail(const std::string& message, const std::string& key = {}) const;

  static std::string describe(const nlohmann::json& v);  // short rendering of a value for messages

  // Parses a whole document as nlohmann::json::parse does, but also rejects a key given twice in
  // one object (the last one would silently win) and nesting deeper than kMaxDepth (no scene
  // needs it; recursive code further on would overflow the stack). Errors name `file` and the
  // JSON pointer or byte position.
  static constexpr int kMaxDepth = 64;
  static nlohmann::json parse_strict(const std::string& text, const std::string& file);

 private:
  const nlohmann::json* j_;
  std::string path_, file_;
};

}  // namespace lblight
