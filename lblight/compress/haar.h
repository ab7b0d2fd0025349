// The encoder's side of the Haar sub-block scheme (docs/model.md sec. 7, docs/lbh-format.md). The transform
// itself is written once, in the reader (readers/lbh/lbh_reader.h), and used here as is, so the
// encoder and every reader agree on the filters, their order and the coefficient layout.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "lblight/lattice/lattice.h"
#include "readers/lbh/lbh_reader.h"

namespace lblight::haar {

using lbh::haar_forward_1d;
using lbh::haar_forward_block;
using lbh::haar_inverse_1d;
using lbh::haar_inverse_block;

// Three channels of one 4^3 block: value (x, y, z), or coefficient (fx, fy, fz), at x + 4y + 16z.
using Block = std::array<std::array<float, 64>, 3>;

inline int blocks_along(int n) { return static_cast<int>(lbh::detail::blocks_for(n)); }

// The 4^3 values of sub-block (bx, by, bz) from RGB arrays over the lattice (x fastest): node
// (3bx + x, 3by + y, 3bz + z), each coordinate clamped to the last node (forward border).
void gather_block(const std::array<const float*, 3>& rgb, const Dims& d, int bx, int by, int bz, Block& out);

// Forward transform of all three channels.
void forward(Block& b);

// Which coefficients are kept: the average (bit 0) always; a detail coefficient unless it is below
// the threshold in all three channels, |c| < t (t > 0), or exactly zero in all three (any t, so a
// zero threshold is lossless and constant blocks take the fast path).
std::uint64_t keep_mask(const Block& coeffs, float threshold);

// A priori error bound of one block: every reconstructed value is the sum of 27 coefficients with
// signs +-1 (3 per axis: the average, the coarse detail and the fine detail of its pair), so its
// error is at most the sum of |dropped coefficient| (max over channels) on that path. Returns the
// largest such sum over the 64 values. Since at most 26 details lie on a path and each dropped one
// is below t, the result is < 26 t (0 for t = 0).
float dropped_path_bound(const Block& coeffs, std::uint64_t mask);

// The same for any per-coefficient error (max over channels): the largest sum of error[l] over the
// 27 coefficients on the path of one of the 64 values.
float path_error_bound(const float* error64);

// What dropping costs per coefficient: |c| (max over channels) where the mask drops it, 0 where it
// keeps it. Encoders add what storing a kept one costs.
void dropped_errors(const Block& coeffs, std::uint64_t mask, float* error64);

inline constexpr int kMaxDetailsPerValue = 26;

}  // namespace lblight::haar
