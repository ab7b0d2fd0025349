// The gas solver's per-node rules ([Wei2004], docs/fluid.md): D3Q19 BGK with the equilibrium of
// eq. (9) and its Table 1 coefficients, a body force (buoyancy) by Guo's scheme so that the
// velocity field is second-order accurate, and a D3Q7 advection-diffusion lattice for the
// scalars the flow carries (temperature, smoke). Written once as LBL_HOSTDEV functions over plain
// values, as lattice/collide.h is, so the OpenMP loop and device kernels share them.
#pragma once

#include "lblight/core/hostdev.h"
#include "lblight/lattice/d3q19.h"

namespace lblight::fluid {

// Table 1 of [Wei2004]: f_eq = rho (A + B e.u + C (e.u)^2 + D u^2) per sub-lattice (0: rest,
// 1: the 6 axial directions, 2: the 12 diagonal ones). These are w (1 + 3 e.u + 9/2 (e.u)^2
// - 3/2 u^2) with w = 1/3, 1/18, 1/36: the sound speed is 1/sqrt(3) and nu = (tau - 1/2) / 3.
struct SubLattice {
  double a, b, c, d;
};
LBL_HOSTDEV constexpr SubLattice coefficients(int m) {
  return m == 0 ? SubLattice{1.0 / 3, 0.0, 0.0, -1.0 / 2}
                : (d3q19::is_axial(m) ? SubLattice{1.0 / 18, 1.0 / 6, 1.0 / 4, -1.0 / 12}
                                      : SubLattice{1.0 / 36, 1.0 / 12, 1.0 / 8, -1.0 / 24});
}

template <typename Real>
LBL_HOSTDEV inline Real equilibrium(int m, Real rho, Real ux, Real uy, Real uz) {
  const SubLattice k = coefficients(m);
  const Real eu = Real(d3q19::cx(m)) * ux + Real(d3q19::cy(m)) * uy + Real(d3q19::cz(m)) * uz;
  const Real uu = ux * ux + uy * uy + uz * uz;
  return rho * (Real(k.a) + Real(k.b) * eu + Real(k.c) * eu * eu + Real(k.d) * uu);
}

struct Moments {
  double rho, ux, uy, uz;
};

// Density and velocity of a node's 19 values under force F: u = (sum f e + F / 2) / rho (Guo).
template <typename Real>
LBL_HOSTDEV inline Moments moments(const Real (&f)[d3q19::kQ], double fx, double fy, double fz) {
  double rho = 0, jx = 0, jy = 0, jz = 0;
  LBL_UNROLL
  for (int m = 0; m < d3q19::kQ; ++m) {
    const double v = static_cast<double>(f[m]);
    rho += v;
    jx += v * d3q19::cx(m);
    jy += v * d3q19::cy(m);
    jz += v * d3q19::cz(m);
  }
  const double inv = rho > 0 ? 1.0 / rho : 0.0;
  return {rho, (jx + 0.5 * fx) * inv, (jy + 0.5 * fy) * inv, (jz + 0.5 * fz) * inv};
}

// One BGK collision in place (eq. 8) with Guo's forcing term
//   (1 - 1/(2 tau)) w_m [3 (e_m - u) + 9 (e_m . u) e_m] . F,
// which adds exactly F to the node's momentum and nothing to its mass. Returns the moments.
template <typename Real>
LBL_HOSTDEV inline Moments collide(Real (&f)[d3q19::kQ], double tau, double fx, double fy, double fz) {
  const Moments mo = moments(f, fx, fy, fz);
  const double omega = 1.0 / tau, keep = 1.0 - 0.5 * omega;
  LBL_UNROLL
  for (int m = 0; m < d3q19::kQ; ++m) {
    const double ex = d3q19::cx(m), ey = d3q19::cy(m), ez = d3q19::cz(m);
    const double eu = ex * mo.ux + ey * mo.uy + ez * mo.uz;
    const double w = coefficients(m).a;
    const double force = w * (3.0 * ((ex - mo.ux) * fx + (ey - mo.uy) * fy + (ez - mo.uz) * fz) +
                              9.0 * eu * (ex * fx + ey * fy + ez * fz));
    const double feq = equilibrium<double>(m, mo.rho, mo.ux, mo.uy, mo.uz);
    f[m] = static_cast<Real>(static_cast<double>(f[m]) - omega * (static_cast<double>(f[m]) - feq) + keep * force);
  }
  return mo;
}

// D3Q7 for a scalar s carried by velocity u: g_eq = w s (1 + 4 e.u), w = 1/4 (rest), 1/8
// (axial); the diffusivity is (tau - 1/2) / 4. Direction k of the 7 is d3q19 direction k.
inline constexpr int kQ7 = 7;
LBL_HOSTDEV constexpr double weight7(int k) { return k == 0 ? 0.25 : 0.125; }

LBL_HOSTDEV inline double scalar_equilibrium(int k, double s, double ux, double uy, double uz) {
  const double eu = d3q19::cx(k) * ux + d3q19::cy(k) * uy + d3q19::cz(k) * uz;
  return weight7(k) * s * (1.0 + 4.0 * eu);
}

template <typename Real>
LBL_HOSTDEV inline void collide_scalar(Real (&g)[kQ7], double tau, double ux, double uy, double uz) {
  double s = 0;
  LBL_UNROLL
  for (int k = 0; k < kQ7; ++k) s += static_cast<double>(g[k]);
  const double omega = 1.0 / tau;
  LBL_UNROLL
  for (int k = 0; k < kQ7; ++k) {
    const double geq = scalar_equilibrium(k, s, ux, uy, uz);
    g[k] = static_cast<Real>(static_cast<double>(g[k]) - omega * (static_cast<double>(g[k]) - geq));
  }
}

}  // namespace lblight::fluid
