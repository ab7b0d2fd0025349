#include "lblight/lattice/collision_op.h"
#include "lblight/lattice/collide.h"  // split_pairs
#include "lblight/lattice/cubic_form.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace lblight {

namespace {
constexpr int kQ = d3q19::kQ;
double at(const OmegaMatrix& om, int m, int n) { return om[static_cast<std::size_t>(m) * kQ + n]; }
void expect_equal(double a, double b, const char* what) {
  const double scale = std::max({1.0, std::fabs(a), std::fabs(b)});
  if (std::fabs(a - b) > 1e-12 * scale)
    throw std::invalid_argument(std::string("collision matrix is not centrally symmetric: ") + what);
}
// Inverse of an n x n matrix (row-major) by Gauss-Jordan with partial pivoting; false if singular.
bool invert(std::vector<double> a, int n, std::vector<double>& inv) {
  inv.assign(static_cast<std::size_t>(n) * n, 0.0);
  for (int i = 0; i < n; ++i) inv[static_cast<std::size_t>(i) * n + i] = 1.0;
  auto A = [&](int r, int c) -> double& { return a[static_cast<std::size_t>(r) * n + c]; };
  auto I = [&](int r, int c) -> double& { return inv[static_cast<std::size_t>(r) * n + c]; };
  for (int col = 0; col < n; ++col) {
    int piv = col;
    for (int r = col + 1; r < n; ++r)
      if (std::fabs(A(r, col)) > std::fabs(A(piv, col))) piv = r;
    if (std::fabs(A(piv, col)) < 1e-12) return false;
    for (int c = 0; c < n; ++c) {
      std::swap(A(col, c), A(piv, c));
      std::swap(I(col, c), I(piv, c));
    }
    const double d = A(col, col);
    for (int c = 0; c < n; ++c) {
      A(col, c) /= d;
      I(col, c) /= d;
    }
    for (int r = 0; r < n; ++r) {
      if (r == col || A(r, col) == 0.0) continue;
      const double m = A(r, col);
      for (int c = 0; c < n; ++c) {
        A(r, c) -= m * A(col, c);
        I(r, c) -= m * I(col, c);
      }
    }
  }
  return true;
}

// Omega in the coordinates of cubic_form.h: K = rows^-1 Omega' coords^-1, where coords maps a
// state to c and rows maps C to Omega f in (s_0, E, O) form. Fills op.cubic and sets is_cubic when
// K has nothing outside the blocks cubic_blocks applies (to 1e-12 of its largest entry).
void fit_cubic(const OmegaMatrix& om, CollisionOp<double>& op) {
  constexpr int n = kCubicCoords;
  std::vector<double> coords(n * n), rows(n * n);
  for (int j = 0; j < n; ++j) {  // column j: the image of unit vector j
    double f[kQ] = {}, e[kPairs], o[kPairs], c[n];
    f[j] = 1.0;
    split_pairs(f, e, o);
    cubic_coords(f[0], e, o, c);
    for (int i = 0; i < n; ++i) coords[static_cast<std::size_t>(i) * n + j] = c[i];
    double C[n] = {}, s0, E[kPairs], O[kPairs];
    C[j] = 1.0;
    cubic_rows(C, s0, E, O);
    rows[j] = s0;
    for (int p = 0; p < kPairs; ++p) {
      rows[static_cast<std::size_t>(1 + p) * n + j] = E[p];
      rows[static_cast<std::size_t>(1 + kPairs + p) * n + j] = O[p];
    }
  }
  // Omega in (s_0, E, O) form: row 0 as it is, E and O the half sum and half difference of a
  // pair's rows.
  std::vector<double> h(n * n);
  for (int j = 0; j < n; ++j) {
    h[j] = at(om, 0, j);
    for (int p = 0; p < kPairs; ++p) {
      const double a = at(om, 2 * p + 1, j), b = at(om, 2 * p + 2, j);
      h[static_cast<std::size_t>(1 + p) * n + j] = 0.5 * (a + b);
      h[static_cast<std::size_t>(1 + kPairs + p) * n + j] = 0.5 * (a - b);
    }
  }
  std::vector<double> coords_inv, rows_inv;
  if (!invert(coords, n, coords_inv) || !invert(rows, n, rows_inv)) return;
  auto product = [&](const std::vector<double>& x, const std::vector<double>& y) {
    std::vector<double> z(n * n, 0.0);
    for (int i = 0; i < n; ++i)
      for (int l = 0; l < n; ++l)
        for (int j = 0; j < n; ++j)
          z[static_cast<std::size_t>(i) * n + j] +=
              x[static_cast<std::size_t>(i) * n + l] * y[static_cast<std::size_t>(l) * n + j];
    return z;
  };
  const std::vector<double> k = product(rows_inv, product(h, coords_inv));
  // Read the coefficients off K, then rebuild K from them through cubic_blocks: whatever differs
  // lies outside the blocks (or differs between components the symmetry makes equal).
  auto K = [&](int r, int c) { return k[static_cast<std::size_t>(r) * n + c]; };
  double* q = op.cubic;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) q[3 * r + c] = K(r, c);
  q[9] = K(3, 3), q[10] = K(3, 4), q[11] = K(4, 3), q[12] = K(4, 4);
  q[13] = K(5, 5), q[14] = K(5, 6), q[15] = K(6, 5), q[16] = K(6, 6);
  q[17] = K(7, 7);
  q[18] = K(10, 10), q[19] = K(10, 13), q[20] = K(13, 10), q[21] = K(13, 13);
  q[22] = K(16, 16);
  double largest = 0.0, worst = 0.0;
  for (double v : k) largest = std::max(largest, std::fabs(v));
  for (int j = 0; j < n; ++j) {
    double c[n] = {}, C[n];
    c[j] = 1.0;
    cubic_blocks(q, c, C);
    for (int i = 0; i < n; ++i) worst = std::max(worst, std::fabs(C[i] - K(i, j)));
  }
  op.is_cubic = worst <= 1e-12 * std::max(largest, 1e-300) ? 1 : 0;
  if (!op.is_cubic) std::fill(std::begin(op.cubic), std::end(op.cubic), 0.0);
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
  fit_cubic(om, op);
  return op;
}

}  // namespace lblight
