// Accelerated steady state: BiCGStab on (I - A) x = b, where one LB step is T(x) = A x + b
// with the boundary values fixed (the plain iteration x <- T(x) converges to the same x).
// Written once against LatticeSolver's vector operations, so it runs on every backend; it
// solves system 0 of the solver's current batch and leaves the solution as that system's state.
#pragma once

#include <atomic>
#include <functional>

#include "lblight/backend/backend.h"

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
KrylovResult bicgstab(LatticeSolver& solver, double tolerance, int max_steps,
                      const std::atomic<bool>* cancel = nullptr, const KrylovProgress& progress = {});

}  // namespace lblight
