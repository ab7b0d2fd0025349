// Optical materials per colour channel, and the named presets from the papers.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "lblight/lattice/omega.h"

namespace lblight {

inline constexpr int kChannels = 3;
inline constexpr const char* kChannelNames[kChannels] = {"red", "green", "blue"};

struct Material {
  std::string name = "custom";              // preset name, or "custom"
  std::array<OpticalParams, kChannels> channel{};
  bool absorbs = false;                      // dump f_0 every step (leaves); docs/model.md sec. 3
  bool channels_equal() const;
};

// cloud ([Geist2010] sec. 3.2.1), dogrose ([Geist2010] Table 1), pmma ([Geist2010] Table 2), leaf ([Steele2009] Table 6.1),
// bark (physical wood: opaque, brown, diffusely reflecting; docs/model.md "Wood"), paper-bark (the
// papers' wood: leaf sigmas with g = -1, no f_0 dump: [Steele2009] sec. 4.1).
std::optional<Material> material_preset(const std::string& name);
std::vector<std::string> material_preset_names();

// [Steele2009] eq. (4.3): g = (fs - bs) / (fs + bs) from forward and backward scattering fractions.
double g_from_forward_backward(double fs, double bs);

// [Steele2009] Table 6.1 as printed, for the leaf preset and its test.
struct LeafTable {
  std::array<double, kChannels> sigma_a, sigma_s, fs, bs, g_printed;
};
const LeafTable& leaf_table_6_1();

// The default wood material for a given leaf/medium material (docs/model.md sec. 3): the same sigmas,
// g = -1 (backward only), no f_0 dump.
Material default_wood_for(const Material& medium);

// The wood of a model that names none: the papers' wood (above) in the papers' LB model, the
// physical `bark` preset in the calibrated one, so that a default scene's trunks shade like bark.
Material default_wood(const Material& medium, bool calibrated);

}  // namespace lblight
