// Leaf ("green") or wood ("brown") per mesh part, by name patterns ([Steele2009] sec. 4.1: a node is brown
// when wood occupies more of it than leaves, so every triangle must be one or the other).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "lblight/mesh/triangle_mesh.h"

namespace lblight {

enum class TriangleClass : std::uint8_t { Leaf = 0, Wood = 1 };

// Defaults that match common plant exports (Xfrog, Sapling, SpeedTree-style names).
const std::vector<std::string>& default_leaf_patterns();  // leaf, leaves, foliage, needle
const std::vector<std::string>& default_wood_patterns();  // bark, trunk, branch, wood, stem

// A pattern matches a name case-insensitively: as a substring, or, when it contains `*` or `?`,
// as a glob over the whole name.
bool name_matches(const std::string& pattern, const std::string& name);

struct Classification {
  std::vector<TriangleClass> part_class;  // per mesh part
  std::vector<std::string> part_reason;   // per part: which name and pattern decided, or "unmatched"
  std::size_t leaf_triangles = 0, wood_triangles = 0;
  std::size_t unmatched_triangles = 0;    // counted as leaf
  std::vector<std::string> unmatched_parts;
};

// Each part is decided by its material name, else its group name, else its object name: the
// first of these that matches any pattern. Within one name the longest (most specific) matching
// pattern wins, a tie goes to leaf. Parts no name of which matches are leaf and are counted.
// Empty pattern lists mean the defaults.
Classification classify_parts(const TriangleMesh& mesh, const std::vector<std::string>& leaf_patterns,
                              const std::vector<std::string>& wood_patterns);

}  // namespace lblight
