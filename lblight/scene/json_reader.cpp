#include "lblight/scene/json_reader.h"

#include <cmath>
#include <cstdio>
#include <set>
#include <vector>

namespace lblight {

namespace {

// The JSON library's message without its "[json.exception.parse_error.101] " tag.
std::string plain_json_message(const std::exception& e) {
  std::string s = e.what();
  if (s.rfind("[json.exception.", 0) == 0) {
    const std::size_t end = s.find("] ");
    if (end != std::string::npos) s = s.substr(end + 2);
  }
  return s;
}

// SAX pass that only checks structure: open containers with the keys seen so far.
class StrictStructure final : public nlohmann::json_sax<nlohmann::json> {
 public:
  explicit StrictStructure(std::string file) : file_(std::move(file)) {}

  bool null() override { return value(); }
  bool boolean(bool) override { return value(); }
  bool number_integer(number_integer_t) override { return value(); }
  bool number_unsigned(number_unsigned_t) override { return value(); }
  bool number_float(number_float_t, const string_t&) override { return value(); }
  bool string(string_t& s) override {
    refuse_control(s, "value");
    return value();
  }
  bool binary(binary_t&) override { return value(); }
  bool start_object(std::size_t) override { return open(true); }
  bool end_object() override { return close(); }
  bool start_array(std::size_t) override { return open(false); }
  bool end_array() override { return close(); }
  bool key(string_t& k) override {
    refuse_control(k, "key");
    Level& l = stack_.back();
    l.key = k;
    if (!l.keys.insert(k).second)
      throw_invalid("key '" + k + "' is given twice in one object; give each field once", {file_, pointer(), {}});
    return true;
  }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception& e) override {
    // Includes numbers too large for a double (1e999): JSON has no Inf or NaN, so a value that
    // would overflow is rejected here, with the offending text and the field in the message.
    const bool overflow = e.id == 406;
    throw_invalid(std::string("not valid JSON: ") + plain_json_message(e) +
                      (overflow ? "; allowed: finite numbers" : ""),
                  {file_, field(), {}});
  }

 private:
  struct Level {
    bool object = false;
    std::size_t index = 0;  // arrays: the element being read
    std::string key;        // objects: the member being read
    std::set<std::string> keys;
  };
  // A NUL would cut a path short where the system reads it ("ok.vdb\u0000/../x" opens ok.vdb) and
  // other control characters reach terminals and scripts: no lblight field needs one.
  void refuse_control(const std::string& s, const char* what) {
    for (std::size_t i = 0; i < s.size(); ++i) {
      const unsigned char c = static_cast<unsigned char>(s[i]);
      if (c < 0x20 || c == 0x7f) {
        char code[8];
        std::snprintf(code, sizeof code, "\\u%04x", c);
        throw_invalid(std::string("a string ") + what + " holds the control character " + code + " at character " +
                          std::to_string(i) + "; allowed: text without control characters",
                      {file_, pointer(), {}});
      }
    }
  }
  bool value() {
    if (!stack_.empty() && !stack_.back().object) ++stack_.back().index;
    return true;
  }
  bool open(bool object) {
    if (static_cast<int>(stack_.size()) >= JsonReader::kMaxDepth)
      throw_invalid("JSON nested deeper than " + std::to_string(JsonReader::kMaxDepth) + " levels; a scene needs a few",
                    {file_, pointer(), {}});
    stack_.push_back({object, 0, {}, {}});
    return true;
  }
  bool close() {
    stack_.pop_back();
    return value();
  }
  // The pointer of the field being read when there is one ("" before the first key).
  std::string field() const {
    if (stack_.empty() || (stack_.size() == 1 && stack_[0].object && stack_[0].key.empty())) return "";
    return pointer();
  }
  // JSON pointer of the value being read (keys unescaped: for messages only).
  std::string pointer() const {
    std::string p;
    for (const Level& l : stack_) p += "/" + (l.object ? l.key : std::to_string(l.index));
    return p.empty() ? "/" : p;
  }

  std::string file_;
  std::vector<Level> stack_;
};

}  // namespace

nlohmann::json JsonReader::parse_strict(const std::string& text, const std::string& file) {
  StrictStructure check(file);
  nlohmann::json::sax_parse(text, &check);
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {  // not expected after the pass above
    throw_invalid(std::string("not valid JSON: ") + plain_json_message(e), {file, {}, {}});
  }
}

std::string JsonReader::describe(const nlohmann::json& v) {
  std::string s = v.dump();
  if (s.size() > 60) s = s.substr(0, 57) + "...";
  return s;
}

void JsonReader::fail(const std::string& message, const std::string& key) const {
  throw_invalid(message, location(key));
}

void JsonReader::expect_object() const {
  if (!j_->is_object()) fail("expected a JSON object, found " + describe(*j_));
}

JsonReader JsonReader::child(const std::string& key) const {
  expect_object();
  if (!j_->contains(key)) fail("required field '" + key + "' is missing", key);
  return JsonReader(j_->at(key), path_of(key), file_);
}

JsonReader JsonReader::element(std::size_t index) const {
  return JsonReader(j_->at(index), path_ + "/" + std::to_string(index), file_);
}

std::string JsonReader::string(const std::string& key) const {
  const JsonReader c = child(key);
  if (!c.json().is_string()) c.fail("expected a string, found " + describe(c.json()));
  return c.json().get<std::string>();
}

std::string JsonReader::string_or(const std::string& key, const std::string& fallback) const {
  return has(key) ? string(key) : fallback;
}

double JsonReader::as_number(double lo, double hi, const std::string& allowed) const {
  if (!j_->is_number()) fail("expected a number, found " + describe(*j_) + "; allowed: " + allowed);
  const double v = j_->get<double>();
  if (!std::isfinite(v)) fail("value " + describe(*j_) + " is not finite; allowed: " + allowed);
  if (v < lo || v > hi) fail("value " + describe(*j_) + " is out of range; allowed: " + allowed);
  return v;
}

std::vector<double> JsonReader::as_numbers(std::size_t count, const std::string& shape, double lo, double hi,
                                           const std::string& allowed) const {
  if (!j_->is_array() || j_->size() != count) fail("expected " + shape + ", found " + describe(*j_));
  std::vector<double> out(count);
  for (std::size_t k = 0; k < count; ++k) out[k] = element(k).as_number(lo, hi, allowed);
  return out;
}

double JsonReader::number(const std::string& key, double lo, double hi, const std::string& allowed) const {
  return child(key).as_number(lo, hi, allowed);
}

double JsonReader::number_or(const std::string& key, double fallback, double lo, double hi,
                             const std::string& allowed) const {
  return has(key) ? number(key, lo, hi, allowed) : fallback;
}

long long JsonReader::integer_or(const std::string& key, long long fallback, long long lo, long long hi) const {
  if (!has(key)) return fallback;
  const JsonReader c = child(key);
  const std::string allowed = "an integer in " + std::to_string(lo) + ".." + std::to_string(hi);
  if (!c.json().is_number_integer()) c.fail("expected an integer, found " + describe(c.json()) + "; allowed: " + allowed);
  const long long v = c.json().get<long long>();
  if (v < lo || v > hi) c.fail("value " + describe(c.json()) + " is out of range; allowed: " + allowed);
  return v;
}

bool JsonReader::boolean_or(const std::string& key, bool fallback) const {
  if (!has(key)) return fallback;
  const JsonReader c = child(key);
  if (!c.json().is_boolean()) c.fail("expected true or false, found " + describe(c.json()));
  return c.json().get<bool>();
}

}  // namespace lblight
