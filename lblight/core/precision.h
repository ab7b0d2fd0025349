// Storage precision of lattice state: one value type that the scene, the plan, the backends and
// the output all name, so it lives below all of them.
#pragma once

namespace lblight {

// How lattice state is stored. Arithmetic is float32 for Float16 storage.
enum class Precision { Float32, Float64, Float16 };

inline const char* to_string(Precision p) {
  switch (p) {
    case Precision::Float32: return "float32";
    case Precision::Float64: return "float64";
    case Precision::Float16: return "float16";
  }
  return "?";
}

// How many copies of the lattice state a solver keeps (docs/performance.md, "In-place
// streaming"): two time levels, or one updated in place by the AA pattern (half the state
// memory, the same bits, no temporal blocking).
enum class StateLayout { TwoLevels, InPlace };

inline const char* to_string(StateLayout s) { return s == StateLayout::InPlace ? "in-place" : "two-levels"; }

inline double bytes_per_value(Precision p) {
  return p == Precision::Float64 ? 8.0 : (p == Precision::Float16 ? 2.0 : 4.0);
}

}  // namespace lblight
