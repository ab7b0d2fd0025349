// Runs a piece of work that may crash or hang on hostile input (a third-party parser fed a
// corrupt file) in a child process, so that a crash or a hang there becomes an error here
// (docs/reliability.md). The child is a fork of this process: the work must not need other
// threads (no TBB, no OpenMP) and must only read.
#pragma once

#include <functional>
#include <mutex>
#include <string>

#include "lblight/core/run_context.h"

namespace lblight {

struct IsolatedOutcome {
  enum class Kind { Ok, Threw, Crashed, TimedOut, Cancelled } kind = Kind::Ok;
  std::string message;  // Threw: the exception's message; Crashed: the signal; TimedOut: the limit
};

// Calls `work` in a forked child and waits (polling ctx.cancel) at most `timeout_seconds`. The
// child reports an exception's message back through a pipe; a child that dies of a signal, or
// is still running at the timeout or at cancellation, is killed and reported as such.
// memory_bytes > 0: the child may allocate at most that much beyond what it inherits (an
// allocation past it fails in the child, never the machine's memory).
IsolatedOutcome run_isolated(const std::function<void()>& work, double timeout_seconds, const RunContext& ctx = {},
                             std::size_t memory_bytes = 0);

// Held while this process may be loading shared libraries on another thread (starting a GPU
// driver): a fork then would copy the loader mid-change, and the child aborts inside ld.so (seen
// as "Inconsistency detected by ld.so" under ASan). run_isolated forks only while holding it.
std::unique_lock<std::mutex> hold_forks();

}  // namespace lblight
