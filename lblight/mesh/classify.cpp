#include "lblight/mesh/classify.h"

#include <cctype>

namespace lblight {
namespace {

char lower(char c) { return static_cast<char>(std::tolower(static_cast<unsigned char>(c))); }

// Iterative glob with backtracking to the last '*' (linear in practice).
bool glob(const std::string& p, const std::string& s) {
  std::size_t pi = 0, si = 0, star = std::string::npos, mark = 0;
  while (si < s.size()) {
    if (pi < p.size() && (p[pi] == '?' || lower(p[pi]) == lower(s[si]))) {
      ++pi;
      ++si;
    } else if (pi < p.size() && p[pi] == '*') {
      star = pi++;
      mark = si;
    } else if (star != std::string::npos) {
      pi = star + 1;
      si = ++mark;
    } else {
      return false;
    }
  }
  while (pi < p.size() && p[pi] == '*') ++pi;
  return pi == p.size();
}

// Characters that must match literally: how specific a pattern is.
std::size_t specificity(const std::string& p) {
  std::size_t n = 0;
  for (char c : p) n += c != '*' && c != '?';
  return n;
}

// Best match of one name: 0 none, else specificity; `wood` tells which list won.
std::size_t best_match(const std::string& name, const std::vector<std::string>& leaf,
                       const std::vector<std::string>& wood, bool& is_wood, std::string& pattern) {
  std::size_t best = 0;
  for (int list = 0; list < 2; ++list)
    for (const std::string& p : list == 0 ? leaf : wood)
      if (name_matches(p, name)) {
        const std::size_t s = specificity(p) + 1;  // +1: an all-wildcard pattern still counts
        if (s > best) {  // strictly greater: on a tie the leaf list (looked at first) keeps it
          best = s;
          is_wood = list == 1;
          pattern = p;
        }
      }
  return best;
}

}  // namespace

const std::vector<std::string>& default_leaf_patterns() {
  static const std::vector<std::string> p{"leaf", "leaves", "foliage", "needle"};
  return p;
}

const std::vector<std::string>& default_wood_patterns() {
  static const std::vector<std::string> p{"bark", "trunk", "branch", "wood", "stem"};
  return p;
}

bool name_matches(const std::string& pattern, const std::string& name) {
  if (pattern.find_first_of("*?") != std::string::npos) return glob(pattern, name);
  if (pattern.size() > name.size()) return false;
  for (std::size_t i = 0; i + pattern.size() <= name.size(); ++i) {
    std::size_t k = 0;
    while (k < pattern.size() && lower(pattern[k]) == lower(name[i + k])) ++k;
    if (k == pattern.size()) return true;
  }
  return false;
}

Classification classify_parts(const TriangleMesh& mesh, const std::vector<std::string>& leaf_patterns,
                              const std::vector<std::string>& wood_patterns) {
  const auto& leaf = leaf_patterns.empty() ? default_leaf_patterns() : leaf_patterns;
  const auto& wood = wood_patterns.empty() ? default_wood_patterns() : wood_patterns;
  Classification c;
  c.part_class.assign(mesh.parts.size(), TriangleClass::Leaf);
  c.part_reason.assign(mesh.parts.size(), "unmatched");
  std::vector<bool> matched(mesh.parts.size(), false);
  for (std::size_t i = 0; i < mesh.parts.size(); ++i) {
    const MeshPart& part = mesh.parts[i];
    const std::pair<const char*, const std::string*> names[] = {
        {"material", &part.material}, {"group", &part.group}, {"object", &part.object}};
    for (const auto& [what, name] : names) {
      if (name->empty()) continue;
      bool is_wood = false;
      std::string pattern;
      if (best_match(*name, leaf, wood, is_wood, pattern) > 0) {
        c.part_class[i] = is_wood ? TriangleClass::Wood : TriangleClass::Leaf;
        c.part_reason[i] = std::string(what) + " '" + *name + "' matches " + (is_wood ? "wood" : "leaf") +
                           " pattern '" + pattern + "'";
        matched[i] = true;
        break;
      }
    }
  }
  std::vector<std::size_t> per_part(mesh.parts.size(), 0);
  for (std::uint32_t p : mesh.triangle_part) ++per_part[p];
  for (std::size_t i = 0; i < mesh.parts.size(); ++i) {
    if (c.part_class[i] == TriangleClass::Wood) c.wood_triangles += per_part[i];
    else c.leaf_triangles += per_part[i];
    if (!matched[i] && per_part[i] > 0) {
      c.unmatched_triangles += per_part[i];
      const MeshPart& p = mesh.parts[i];
      std::string label = "material '" + p.material + "', group '" + p.group + "', object '" + p.object + "'";
      c.unmatched_parts.push_back(label);
    }
  }
  return c;
}

}  // namespace lblight
