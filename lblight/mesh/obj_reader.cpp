#include "lblight/core/input_file.h"
#include "lblight/mesh/obj_reader.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <tuple>
#include <vector>

namespace lblight {
namespace {

std::vector<std::string_view> split_ws(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < s.size() && s[i] != ' ' && s[i] != '\t') ++i;
    if (i > start) out.push_back(s.substr(start, i - start));
  }
  return out;
}

// A token for a message: hostile files hold megabyte-long "numbers".
std::string quoted(std::string_view t) {
  constexpr std::size_t kMax = 40;
  return t.size() <= kMax ? std::string(t) : std::string(t.substr(0, kMax)) + "...";
}

// The longest line an OBJ file may have (a face of 10000 vertices takes ~100 KB).
constexpr std::size_t kMaxLineBytes = 1u << 20;

std::string trimmed_rest(std::string_view line, std::size_t keyword_len) {
  std::string_view s = line.substr(std::min(keyword_len, line.size()));
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return std::string(s);
}

class ObjParser {
 public:
  ObjParser(std::string name, Location where) : name_(std::move(name)), where_(std::move(where)) {
    mesh_.source = name_;
  }

  [[noreturn]] void fail(const std::string& what) const {
    throw_invalid(name_ + ":" + std::to_string(line_no_) + ": " + what, where_);
  }

  // One line into `raw`, at most kMaxLineBytes, refusing binary data; false at the end.
  bool next_line(std::istream& in, std::string& raw) {
    raw.clear();
    std::streambuf* buf = in.rdbuf();
    for (;;) {
      const int c = buf->sbumpc();
      if (c == std::char_traits<char>::eof()) {
        in.setstate(std::ios::eofbit);
        return !raw.empty();
      }
      if (c == '\n') return true;
      if (c == 0) {
        ++line_no_;
        fail("holds binary data (a NUL byte); allowed: a text Wavefront OBJ file");
      }
      raw.push_back(static_cast<char>(c));
      if (raw.size() > kMaxLineBytes) {
        ++line_no_;
        fail("line is longer than " + std::to_string(kMaxLineBytes) + " bytes; allowed: text lines of an OBJ file");
      }
    }
  }

  void parse(std::istream& in) {
    std::string raw, line;
    while (next_line(in, raw)) {
      ++line_no_;
      if (!raw.empty() && raw.back() == '\r') raw.pop_back();
      // A trailing backslash continues the statement on the next line.
      if (!raw.empty() && raw.back() == '\\') {
        raw.back() = ' ';
        line += raw;
        continue;
      }
      line += raw;
      if (line.size() > kMaxLineBytes) fail("statement is longer than " + std::to_string(kMaxLineBytes) + " bytes");
      statement(line);
      line.clear();
    }
    if (!line.empty()) statement(line);
    if (in.bad()) throw_io("cannot read mesh file " + name_, where_);
    if (max_positive_index_ > mesh_.vertices.size()) {
      line_no_ = max_index_line_;
      fail("face refers to vertex " + std::to_string(max_positive_index_) + " but the file defines only " +
           std::to_string(mesh_.vertices.size()) + " vertices");
    }
  }

  TriangleMesh take() { return std::move(mesh_); }

 private:
  void statement(const std::string& line) {
    const std::size_t hash = line.find('#');
    const std::string_view body = std::string_view(line).substr(0, hash);
    const auto tok = split_ws(body);
    if (tok.empty()) return;
    const std::string_view key = tok[0];
    const std::size_t after_key = static_cast<std::size_t>(key.data() - body.data()) + key.size();
    if (key == "v") vertex(tok);
    else if (key == "f" || key == "fo") face(tok);
    else if (key == "o") {  // a new object starts without the previous object's group
      part_.object = trimmed_rest(body, after_key);
      part_.group.clear();
      part_dirty_ = true;
    }
    else if (key == "g") { part_.group = trimmed_rest(body, after_key); part_dirty_ = true; }
    else if (key == "usemtl") { part_.material = trimmed_rest(body, after_key); part_dirty_ = true; }
    else if (key == "vt" || key == "vn" || key == "vp" || key == "s" || key == "mtllib") return;
    else if (key == "l" || key == "p") ++mesh_.ignored_lines;
    else ++mesh_.unknown_statements;
  }

  double number(std::string_view t, const char* what) const {
    double x = 0;
    const char* end = t.data() + t.size();
    const char* first = t.data();
    if (!t.empty() && t[0] == '+') ++first;  // from_chars does not take a leading '+'
    const auto r = std::from_chars(first, end, x);
    if (r.ec == std::errc::result_out_of_range || (r.ec == std::errc() && r.ptr == end && !std::isfinite(x)))
      fail(std::string(what) + " '" + quoted(t) + "' is not a finite number");
    if (r.ec != std::errc() || r.ptr != end) fail(std::string(what) + " '" + quoted(t) + "' is not a number");
    return x;
  }

  void vertex(const std::vector<std::string_view>& tok) {
    // v x y z [w] or v x y z r g b: only x y z matter; every value must still be a number.
    if (tok.size() < 4 || tok.size() > 8)
      fail("a vertex needs 3 coordinates (optionally w, or a colour r g b), found " + std::to_string(tok.size() - 1) +
           " values");
    std::array<double, 3> p{};
    for (std::size_t i = 1; i < tok.size(); ++i) {
      const double x = number(tok[i], i <= 3 ? "vertex coordinate" : "vertex value");
      if (i <= 3) p[i - 1] = x;
    }
    mesh_.vertices.push_back(p);
  }

  std::uint32_t vertex_index(std::string_view t) {
    const std::string_view v = t.substr(0, t.find('/'));  // v, v/vt, v//vn, v/vt/vn
    long long idx = 0;
    const auto r = std::from_chars(v.data(), v.data() + v.size(), idx);
    if (v.empty() || r.ec != std::errc() || r.ptr != v.data() + v.size())
      fail("face vertex '" + quoted(t) + "' is not a vertex index");
    if (idx == 0) fail("face vertex index 0 is invalid (OBJ indices start at 1, negative ones count back)");
    const long long n = static_cast<long long>(mesh_.vertices.size());
    if (idx < 0) {
      if (idx < -n)  // (not -idx > n: -INT64_MIN overflows)
        fail("face vertex " + std::to_string(idx) + " points before the first vertex (" + std::to_string(n) +
             " defined so far)");
      return static_cast<std::uint32_t>(n + idx);
    }
    if (idx > 0xffffffffll) fail("face vertex index " + std::to_string(idx) + " is too large");
    // Positive indices may refer forward; checked once the whole file is read.
    if (static_cast<std::size_t>(idx) > max_positive_index_) {
      max_positive_index_ = static_cast<std::size_t>(idx);
      max_index_line_ = line_no_;
    }
    return static_cast<std::uint32_t>(idx - 1);
  }

  void face(const std::vector<std::string_view>& tok) {
    if (tok.size() < 4) fail("a face needs at least 3 vertices, found " + std::to_string(tok.size() - 1));
    if (part_dirty_) {
      const auto key = std::make_tuple(part_.object, part_.group, part_.material);
      auto it = part_index_.find(key);
      if (it == part_index_.end()) {
        it = part_index_.emplace(key, static_cast<std::uint32_t>(mesh_.parts.size())).first;
        mesh_.parts.push_back(part_);
      }
      current_part_ = it->second;
      part_dirty_ = false;
    }
    idx_.clear();
    for (std::size_t i = 1; i < tok.size(); ++i) idx_.push_back(vertex_index(tok[i]));
    if (idx_.size() > 3) ++mesh_.polygons;
    for (std::size_t i = 1; i + 1 < idx_.size(); ++i) {  // fan around the first vertex
      mesh_.triangles.push_back({idx_[0], idx_[i], idx_[i + 1]});
      mesh_.triangle_part.push_back(current_part_);
    }
  }

  std::string name_;
  Location where_;
  TriangleMesh mesh_;
  std::size_t line_no_ = 0;
  MeshPart part_;
  bool part_dirty_ = true;  // the first face creates the (unnamed) default part
  std::uint32_t current_part_ = 0;
  std::map<std::tuple<std::string, std::string, std::string>, std::uint32_t> part_index_;
  std::vector<std::uint32_t> idx_;
  std::size_t max_positive_index_ = 0, max_index_line_ = 0;
};

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

TriangleMesh parse_obj(std::istream& in, const std::string& name, const Location& where) {
  ObjParser p(name, where);
  p.parse(in);
  return p.take();
}

TriangleMesh read_mesh(const std::filesystem::path& file, const Location& where) {
  check_regular_file(file, "mesh file", where);
  const std::string ext = lower(file.extension().string());
  if (ext != ".obj")
    throw_invalid("mesh file " + file.string() + " has an unsupported format '" + ext +
                      "'; allowed: Wavefront OBJ (.obj)",
                  where);
  std::ifstream in(file, std::ios::binary);
  if (!in) throw_io("cannot open mesh file " + file.string(), where);
  TriangleMesh mesh = parse_obj(in, file.string(), where);
  if (mesh.triangles.empty())
    throw_invalid("mesh file " + file.string() + " has no faces (" + std::to_string(mesh.vertices.size()) +
                      " vertices, " + std::to_string(mesh.ignored_lines) +
                      " lines/points); a density needs triangles with area",
                  where);
  return mesh;
}

}  // namespace lblight
