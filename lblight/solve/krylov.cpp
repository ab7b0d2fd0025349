#include "lblight/solve/krylov.h"

#include <cmath>

#include "lblight/core/error.h"

namespace lblight {

namespace {
enum Vec { kX, kR, kRhat, kP, kV, kS, kT, kB, kCount };
}  // namespace

KrylovVectors& krylov_vectors_of(LatticeSolver& solver, const std::string& backend) {
  KrylovVectors* v = solver.krylov_vectors();
  if (!v)
    throw Error(ErrorCategory::Unavailable, "the " + backend + " backend has no Krylov vector operations; use "
                                            "solver method plain");
  return *v;
}

KrylovResult bicgstab(KrylovVectors& s, double tolerance, int max_steps, const RunContext& ctx,
                      const KrylovProgress& progress, KrylovRhs rhs) {
  KrylovResult out;
  s.vectors_reserve(kCount);
  if (rhs == KrylovRhs::FromState) {
    s.vector_from_state(kB);
    s.vector_axpby(0.0, kB, 0.0, kX);
  } else {
    if (rhs == KrylovRhs::StepOffset) s.vector_step_offset(kB);
    s.vector_from_state(kX);
  }
  // (I - A) y into z, in one pass where the backend fuses it
  auto apply_m = [&](int y, int z) {
    s.vector_apply_minus(y, z);
    ++out.steps;
  };
  const double bnorm = std::sqrt(s.vector_dot(kB, kB));
  if (bnorm == 0.0) {  // no light enters: the steady state is 0
    s.vector_axpby(0.0, kB, 0.0, kX);
    s.vector_to_state(kX);
    out.reached = true;
    return out;
  }
  // r = b - (I - A) x
  apply_m(kX, kR);
  s.vector_axpby(1.0, kB, -1.0, kR);
  double rnorm = std::sqrt(s.vector_dot(kR, kR));
  double rho = 1, alpha = 1, omega = 1;
  double rho_next = 0;     // rhat . r, computed with |r| at the end of an iteration
  bool have_rho = false;
  bool restart = true;
  // Each iteration: two fused sweeps (apply_m) and seven vector passes (docs/model.md sec. 3.1):
  // about 24 vector reads and writes against 41 composed of single operations.
  while (rnorm / bnorm > tolerance && out.steps + 2 <= max_steps) {
    ctx.check_cancelled();
    if (restart) {  // (re)start with the shadow residual equal to the residual
      s.vector_axpby(1.0, kR, 0.0, kRhat);
      s.vector_axpby(0.0, kR, 0.0, kP);
      s.vector_axpby(0.0, kR, 0.0, kV);
      rho = alpha = omega = 1;
      restart = false;
      have_rho = false;
    }
    const double rho_new = have_rho ? rho_next : s.vector_dot(kRhat, kR);
    have_rho = false;
    if (std::fabs(rho_new) < 1e-30 * bnorm * bnorm) {
      restart = true;
      continue;
    }
    const double beta = (rho_new / rho) * (alpha / omega);
    // p = r + beta (p - omega v)
    s.vector_combine(1.0, kR, -beta * omega, kV, beta, kP);
    apply_m(kP, kV);
    const double rv = s.vector_dot(kRhat, kV);
    if (rv == 0.0 || !std::isfinite(rv)) {
      restart = true;
      continue;
    }
    alpha = rho_new / rv;
    // s = r - alpha v
    s.vector_combine(1.0, kR, -alpha, kV, 0.0, kS);
    apply_m(kS, kT);
    double tt = 0, ts = 0;
    s.vector_dots(kT, kT, kT, kS, tt, ts);
    omega = tt > 0 ? ts / tt : 0.0;
    // x += alpha p + omega s;  r = s - omega t
    s.vector_combine(alpha, kP, omega, kS, 1.0, kX);
    s.vector_combine(1.0, kS, -omega, kT, 0.0, kR);
    rho = rho_new;
    double rr = 0;
    s.vector_dots(kR, kR, kRhat, kR, rr, rho_next);
    have_rho = true;
    rnorm = std::sqrt(rr);
    ++out.iterations;
    if (!std::isfinite(rnorm)) throw Error(ErrorCategory::Internal, "BiCGStab diverged (non-finite residual)");
    if (omega == 0.0) restart = true;
    if (progress) {
      out.residual = rnorm / bnorm;
      s.vector_to_state(kX);
      progress(out);
    }
  }
  out.residual = rnorm / bnorm;
  out.reached = out.residual <= tolerance;
  s.vector_to_state(kX);
  return out;
}

void sourced_steps(KrylovVectors& s, int steps) {
  for (int k = 0; k < steps; ++k) {
    s.vector_apply(kX, kT);
    s.vector_combine(1.0, kT, 1.0, kB, 0.0, kX);
  }
  s.vector_to_state(kX);
}

}  // namespace lblight
