// Wavefront OBJ reader for voxelisation: vertices, faces (polygons fan-triangulated), and the
// object / group / material names that tell leaves from wood. Texture coordinates, normals,
// smoothing groups and material libraries are not needed and are skipped.
#pragma once

#include <filesystem>
#include <istream>
#include <string>

#include "lblight/core/error.h"
#include "lblight/mesh/triangle_mesh.h"

namespace lblight {

// Reads a mesh file by extension (.obj). Throws Error(InvalidInput) for a missing file, an
// unsupported format, a malformed line ("file:line: what"), non-finite vertices, face indices
// out of range and a mesh without faces; Error(Io) when the file exists but cannot be read.
// `where` (a scene file and JSON path, or empty) is attached to every error.
TriangleMesh read_mesh(const std::filesystem::path& file, const Location& where = {});

// The OBJ parser on a stream; `name` is used in messages. Does not reject an empty mesh.
TriangleMesh parse_obj(std::istream& in, const std::string& name, const Location& where = {});

}  // namespace lblight
