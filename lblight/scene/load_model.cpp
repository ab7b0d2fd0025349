#include "lblight/scene/load_model.h"

#include "lblight/core/error.h"
#include "lblight/io/vdb_io.h"
#include "lblight/scene/gas_source.h"
#include "lblight/scene/mesh_source.h"
#include "lblight/scene/procedural.h"
#include "lblight/scene/validate.h"

namespace lblight {

ModelGrid load_model_grid(const ModelSpec& model, const Scene& scene, const RunContext& ctx) {
  ModelGrid g;
  switch (model.density.type) {
    case SourceType::Procedural:
      g = make_procedural(model.density.procedural, {scene.file.string(), model.density.json_path + "/resolution", {}},
                          ctx);
      break;
    case SourceType::Vdb: {
      const VdbSource& v = model.density.vdb;
      g = read_vdb_density(v.path, v.grid, v.wood_grid, {scene.file.string(), model.density.json_path, {}}, ctx);
      break;
    }
    case SourceType::Mesh: g = load_mesh_density(model.density.mesh, {scene.file.string(), model.density.json_path, {}}, ctx);
      break;
    case SourceType::Gas: g = make_gas_density(model.density.gas, {scene.file.string(), model.density.json_path, {}}, ctx);
      break;
  }
  ctx.check_cancelled();  // a procedural or .vdb source does not poll
  return finish_model_grid(model, scene, std::move(g));
}

ModelGrid finish_model_grid(const ModelSpec& model, const Scene& scene, ModelGrid g) {
  // NaN stays NaN through the scale and is reported below with its voxel.
  const float scale = static_cast<float>(model.density.density_scale);
  if (scale != 1.0f)
    for (float& d : g.density) d *= scale;
  check_density_values(model, g, scene);
  for (std::size_t i = 0; i < g.density.size(); ++i)
    if (g.density[i] == 0.0f) g.material[i] = kMaterialMedium;
  return g;
}

}  // namespace lblight
