// Accelerated steady state: BiCGStab on (I - A) x = b, where one LB step is T(x) = A x + b
// with the boundary values fixed (the plain iteration x <- T(x) converges to the same x).
// Written once against a solver's KrylovVectors, so it runs on every backend that offers them; it
// solves system 0 of the solver's current batch and leaves the solution as that system's state.
#pragma once

#include <functional>
#include <string>

#include "lblight/backend/backend.h"
#include "lblight/core/run_context.h"

namespace lblight {

struct KrylovResult {
  int iterations = 0;
  int steps = 0;               // LB steps spent (applications of A, the cost unit of plain iteration)
  double residual = 0;         // ||b - (I - A) x|| / ||b|| at the end (recursively updated)
  bool reached = false;        // residual below the requested tolerance
};

// Called after every iteration with system 0's state already set to the current iterate (so a
// caller can measure it); costs a copy per iteration, so only reports use it.
using KrylovProgress = std::function<void(const KrylovResult&)>;

// Starts from system 0's current state. Stops at relative residual `tolerance` or after
// `max_steps` applications of A.
// The Krylov part of `solver` (backend.h); Error(Unavailable) naming `backend` when it has none.
KrylovVectors& krylov_vectors_of(LatticeSolver& solver, const std::string& backend);

// Where b comes from: T(0), what the boundary feeds (x starts from the state); system 0's state,
// a volume source with the boundary values 0 (solve/first_collision.h; x starts from 0); or kept
// from the previous call (x starts from the state: a sourced solve taken further).
enum class KrylovRhs { StepOffset, FromState, Kept };
KrylovResult bicgstab(KrylovVectors& vectors, double tolerance, int max_steps, const RunContext& ctx = {},
                      const KrylovProgress& progress = {}, KrylovRhs rhs = KrylovRhs::StepOffset);

// After a sourced bicgstab (KrylovRhs::FromState or Kept): `steps` plain steps x <- A x + b of the
// same system, leaving x as system 0's state (what the bake's checks measure).
void sourced_steps(KrylovVectors& vectors, int steps);

}  // namespace lblight
