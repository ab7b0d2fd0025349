#pragma once

namespace lblight {
inline constexpr const char* kVersion = "0.1.0";
// Bumped whenever the on-disk layout of bake outputs (grid names, metadata, manifest) changes.
inline constexpr int kManifestFormat = 1;
}  // namespace lblight
