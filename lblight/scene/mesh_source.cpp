#include "lblight/scene/mesh_source.h"

namespace lblight {

ModelGrid load_mesh_density(const MeshSource& source, const Location& where) {
  throw Error(ErrorCategory::Unavailable,
              "mesh density sources (" + source.path.string() + ") are not implemented in this build yet; "
              "voxelize the mesh to a .vdb and use a 'vdb' source",
              where);
}

}  // namespace lblight
