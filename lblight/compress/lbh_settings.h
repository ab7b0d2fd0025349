// What a Haar sub-block stream is compressed with (docs/lbh-format.md secs. 3.3-3.4): shared by
// the encoder, the scene's output section and the compress command.
#pragma once

#include <optional>
#include <string>

namespace lblight {

// How kept coefficients are stored (docs/lbh-format.md sec. 2.3): F32 as [Steele2009] does; Q8 keeps each
// block's average in f32 and stores details as 8-bit multiples of a per-solution step of half
// the threshold, coarser only when the largest kept detail exceeds 63.5 steps (not for
// non-negative totals at relative thresholds >= 1%), so quantising a kept detail usually costs a
// quarter of what dropping one may; Auto is Q8 when the applied threshold is > 0, else F32.
enum class LbhCoefficients { Auto, F32, Q8 };

// The threshold, absolute or relative to the solution's largest |value| over all nodes and
// channels, and the coefficient storage.
struct LbhSettings {
  double value = 0.0;  // the threshold
  bool relative = false;
  LbhCoefficients coefficients = LbhCoefficients::Auto;
};

// "auto", "f32", "q8" (what scenes and the command line accept), or nullopt.
inline std::optional<LbhCoefficients> parse_lbh_coefficients(const std::string& name) {
  if (name == "auto") return LbhCoefficients::Auto;
  if (name == "f32") return LbhCoefficients::F32;
  if (name == "q8") return LbhCoefficients::Q8;
  return std::nullopt;
}

}  // namespace lblight
