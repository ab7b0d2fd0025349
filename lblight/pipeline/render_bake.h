// What `lblight render` draws, loaded from files: a model of a bake folder (relit for the sun from
// its base solutions, materials from the manifest), a bake's model .vdb, or a relit .vdb (one
// model's or a forest's `light` + `density` [+ `brown`] grids, with the material named by the
// caller) - docs/rendering.md.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include "lblight/core/run_context.h"
#include "lblight/pipeline/relight.h"
#include "lblight/render/volume_render.h"

namespace lblight {

// How the indirect term in-scatters the LB light: with the material's phase function from the
// light's flux (the default; needs the bake's moments), or isotropically (bakes without moments).
enum class Scattering { PhaseP1, Isotropic };

struct RenderSource {
  std::filesystem::path input;   // bake folder, bake .vdb or relit .vdb
  std::string model;             // bake folder: which model (needed when it holds several)
  std::optional<std::string> material, wood_material;  // presets, for a relit .vdb (override the manifest's)
  bool light = true;             // load the LB light (false: direct term only)
  Scattering scattering = Scattering::PhaseP1;  // PhaseP1: the flux too, refused when missing
  std::string grid;              // --grid: this grid into RenderVolume::field (its channels' mean),
                                 // no light and no materials needed
};

// Error(InvalidInput) naming the file when it is none of the above, when the materials are not
// known (a relit .vdb without --material), when a base solution the sun needs is missing, or when
// the file has no grid `source.grid` (the message lists those it has).
RenderVolume load_render_volume(const RenderSource& source, const RelightRequest& sun, const RunContext& ctx = {});

}  // namespace lblight
