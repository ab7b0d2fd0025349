// A triangle soup as read from a mesh file: shared vertices, triangles, and for every triangle
// the named part (object, group, material) it came from, so that leaf ("green") and wood
// ("brown") triangles can be told apart by name ([Steele2009] sec. 4.1).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace lblight {

// One combination of OBJ `o`, `g` and `usemtl` in force when a face was read.
struct MeshPart {
  std::string object, group, material;
  bool operator==(const MeshPart& o) const { return object == o.object && group == o.group && material == o.material; }
};

struct TriangleMesh {
  std::vector<std::array<double, 3>> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;  // indices into vertices
  std::vector<std::uint32_t> triangle_part;              // per triangle: index into parts
  std::vector<MeshPart> parts;
  std::string source;                                    // file name, for messages

  // What the reader skipped, for the report (none of it is an error).
  std::size_t polygons = 0;        // faces with more than 3 vertices (fan-triangulated)
  std::size_t ignored_lines = 0;   // `l` lines and `p` points: no area, nothing to voxelize
  std::size_t unknown_statements = 0;  // keywords the reader does not use (curves, surfaces, ...)
};

}  // namespace lblight
