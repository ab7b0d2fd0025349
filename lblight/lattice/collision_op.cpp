#include "lblight/lattice/collision_op.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace lblight {

namespace {
constexpr int kQ = d3q19::kQ;
double at(const OmegaMatrix& om, int m, int n) { return om[static_cast<std::size_t>(m) * kQ + n]; }
void expect_equal(double a, double b, const char* what) {
  const double scale = std::max({1.0, std::fabs(a), std::fabs(b)});
  if (std::fabs(a - b) > 1e-12 * scale)
    throw std::invalid_argument(std::string("collision matrix is not centrally symmetric: ") + what);
}
}  // namespace

CollisionOp<double> reduce_omega(const OmegaMatrix& om, bool voxel_average) {
  CollisionOp<double> op{};
  op.diag0 = at(om, 0, 0);
  for (int m = 0; m < kPairs; ++m) {
    const int am = 2 * m + 1, bm = 2 * m + 2;
    expect_equal(at(om, am, 0), at(om, bm, 0), "column 0");
    expect_equal(at(om, 0, am), at(om, 0, bm), "row 0");
    op.col0[m] = 0.5 * (at(om, am, 0) + at(om, bm, 0));
    op.row0[m] = 0.5 * (at(om, 0, am) + at(om, 0, bm));
    for (int k = 0; k < kPairs; ++k) {
      const int ak = 2 * k + 1, bk = 2 * k + 2;
      expect_equal(at(om, am, ak), at(om, bm, bk), "(a, a) vs (b, b)");
      expect_equal(at(om, am, bk), at(om, bm, ak), "(a, b) vs (b, a)");
      // Average the two equal halves so rounding in Omega cannot break the symmetry.
      const double same = 0.5 * (at(om, am, ak) + at(om, bm, bk));
      const double cross = 0.5 * (at(om, am, bk) + at(om, bm, ak));
      op.even[m * kPairs + k] = 0.5 * (same + cross);
      op.odd[m * kPairs + k] = 0.5 * (same - cross);
    }
    if (voxel_average) {  // column 0 sums to zero in every model: f_0 needs no gain
      double sum = 0.0;
      for (int i = 0; i < kQ; ++i) sum += at(om, i, am);
      op.total_gain[m] = 0.5 * sum;
    }
  }
  return op;
}

}  // namespace lblight
