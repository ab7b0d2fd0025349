#include "lblight/scene/material.h"

namespace lblight {

bool Material::channels_equal() const {
  for (int c = 1; c < kChannels; ++c)
    if (channel[c].sigma_a != channel[0].sigma_a || channel[c].sigma_s != channel[0].sigma_s ||
        channel[c].g != channel[0].g)
      return false;
  return true;
}

double g_from_forward_backward(double fs, double bs) { return (fs - bs) / (fs + bs); }

const LeafTable& leaf_table_6_1() {
  static const LeafTable t{{0.109, 0.091, 0.118},
                           {0.891, 0.909, 0.882},
                           {0.055, 0.150, 0.020},
                           {0.070, 0.125, 0.040},
                           {-0.120, 0.091, -0.333}};
  return t;
}

namespace {
Material uniform(const char* name, double sa, double ss, double g, bool absorbs) {
  Material m;
  m.name = name;
  for (auto& c : m.channel) c = {sa, ss, g};
  m.absorbs = absorbs;
  return m;
}
Material rgb(const char* name, std::array<double, 3> sa, std::array<double, 3> ss, std::array<double, 3> g,
             bool absorbs) {
  Material m;
  m.name = name;
  for (int c = 0; c < kChannels; ++c) m.channel[c] = {sa[c], ss[c], g[c]};
  m.absorbs = absorbs;
  return m;
}
Material leaf() {
  const LeafTable& t = leaf_table_6_1();
  std::array<double, 3> g{};
  for (int c = 0; c < kChannels; ++c) g[c] = g_from_forward_backward(t.fs[c], t.bs[c]);
  return rgb("leaf", t.sigma_a, t.sigma_s, g, true);
}
}  // namespace

Material default_wood_for(const Material& medium) {
  Material w = medium;
  w.name = medium.name + "-wood";
  for (auto& c : w.channel) c.g = -1.0;
  w.absorbs = false;
  return w;
}

Material default_wood(const Material& medium, bool calibrated) {
  if (calibrated) return *material_preset("bark");
  return default_wood_for(medium);
}

std::optional<Material> material_preset(const std::string& name) {
  if (name == "cloud") return uniform("cloud", 0.008, 0.792, 0.9, false);
  if (name == "dogrose")
    return rgb("dogrose", {0.109, 0.091, 0.118}, {0.891, 0.909, 0.882}, {-0.231, 0.103, -0.750}, true);
  if (name == "pmma") return rgb("pmma", {0.01, 0.01, 0.01}, {0.99, 0.99, 0.99}, {0.80, -0.88, -0.88}, false);
  if (name == "leaf") return leaf();
  if (name == "bark") {
    // Wood as a path trace sees it (docs/model.md, "Wood"): a voxel of bark holds opaque,
    // diffusely reflecting surface, which scatters like a Lambertian sphere (g = -4/9) with the
    // bark's reflectance as albedo, and stops light within a voxel or two (sigma_t = 4 per voxel).
    constexpr double kSigmaT = 4.0;
    constexpr std::array<double, 3> kAlbedo{0.25, 0.17, 0.11};
    std::array<double, 3> sa{}, ss{};
    for (int c = 0; c < kChannels; ++c) {
      ss[c] = kSigmaT * kAlbedo[c];
      sa[c] = kSigmaT - ss[c];
    }
    return rgb("bark", sa, ss, {-4.0 / 9.0, -4.0 / 9.0, -4.0 / 9.0}, true);
  }
  if (name == "paper-bark") {
    Material b = default_wood_for(leaf());
    b.name = "paper-bark";
    return b;
  }
  return std::nullopt;
}

std::vector<std::string> material_preset_names() {
  return {"cloud", "dogrose", "pmma", "leaf", "bark", "paper-bark"};
}

}  // namespace lblight
