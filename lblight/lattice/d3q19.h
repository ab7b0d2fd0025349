// D3Q19 direction tables in the order of the solver contract (docs/model.md sec. 1).
// Functions rather than arrays so that host and device code can share them; with a constant
// argument (unrolled loops) they fold to literals.
#pragma once

#include "lblight/core/hostdev.h"

namespace lblight::d3q19 {

inline constexpr int kQ = 19;

// Components of c_m, packed two bits per direction as c + 1. Pure arithmetic on a constant, so
// an unrolled loop folds them to immediates on the CPU (where a table lookup would block SIMD
// vectorisation) and device code needs no __constant__ copy.
LBL_HOSTDEV constexpr int unpack_component(unsigned long long packed, int m) {
  return static_cast<int>((packed >> (2 * m)) & 3ull) - 1;
}
LBL_HOSTDEV constexpr int cx(int m) { return unpack_component(0x1548889549ull, m); }
LBL_HOSTDEV constexpr int cy(int m) { return unpack_component(0x895609495ull, m); }
LBL_HOSTDEV constexpr int cz(int m) { return unpack_component(0x20a0954955ull, m); }

// Direction pointing the other way: c[opposite(m)] = -c[m].
LBL_HOSTDEV constexpr int opposite(int m) { return m == 0 ? 0 : ((m & 1) ? m + 1 : m - 1); }

LBL_HOSTDEV constexpr bool is_axial(int m) { return m >= 1 && m <= 6; }

// Lattice weight of a moving direction: 1/12 axial, 1/24 diagonal ([Geist2010] eqs. 6-7); 0 for rest.
LBL_HOSTDEV constexpr double weight(int m) {
  return m == 0 ? 0.0 : (is_axial(m) ? 1.0 / 12.0 : 1.0 / 24.0);
}

// Squared length of c_m (1 axial, 2 diagonal, 0 rest).
LBL_HOSTDEV constexpr int length_sq(int m) { return cx(m) * cx(m) + cy(m) * cy(m) + cz(m) * cz(m); }

}  // namespace lblight::d3q19
