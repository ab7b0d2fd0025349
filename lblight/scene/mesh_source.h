// Mesh density sources (voxelised triangle meshes, 001 sec. 5.1).
#pragma once

#include "lblight/core/error.h"
#include "lblight/scene/model_grid.h"
#include "lblight/scene/scene.h"

namespace lblight {

ModelGrid load_mesh_density(const MeshSource& source, const Location& where);

}  // namespace lblight
