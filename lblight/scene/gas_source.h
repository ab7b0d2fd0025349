// The "gas" density source (docs/fluid.md): a scene's GasSource as gas solver settings, the
// simulation run frame by frame, and a frame's smoke as the model grid a bake lights.
#pragma once

#include <functional>
#include <string>

#include "lblight/core/error.h"
#include "lblight/core/run_context.h"
#include "lblight/fluid/gas_solver.h"
#include "lblight/lattice/dense_grid.h"
#include "lblight/scene/scene.h"

namespace lblight {

inline constexpr double kMaxGasSpeed = 0.25;
inline constexpr double kMinGasDensity = 1e-4;  // smoke below this fraction of the inlet's is air

// The solver settings: a floor wall with the round inlet (its nodes from the world centre and
// radius), open sides and top. Error(InvalidInput) at `where` when the inlet misses the floor or
// covers no node, or when the solver refuses the settings (tau, Mach).
fluid::GasSettings gas_settings(const GasSource& source, const Location& where);

// World transform of the simulation's nodes (standing on z = 0, x and y centred).
std::array<double, 16> gas_transform(const GasSource& source);

// Runs frames 1..last (source.frames when 0), calling on_frame(frame, solver) after each.
// Error(InvalidInput) at `where` when the flow gets faster than kMaxGasSpeed (Mach 0.43).
void run_gas(const GasSource& source, int last, const Location& where, const RunContext& ctx,
             const std::function<void(int, const fluid::GasSolver&)>& on_frame);

// The smoke of the solver's current state as a density grid: concentration / inlet smoke,
// clamped to [0, 1], and 0 below kMinGasDensity.
ModelGrid gas_density(const GasSource& source, const fluid::GasSolver& solver);

// "<model>.NNNN": a frame's file name without ".vdb" and, lit, its manifest entry (one file per
// frame, numbered as Blender and Houdini read sequences).
std::string gas_frame_name(const std::string& model, int frame);

// The frame a bake lights (source.frame, 0 = the last), simulated.
ModelGrid make_gas_density(const GasSource& source, const Location& where, const RunContext& ctx);

}  // namespace lblight
