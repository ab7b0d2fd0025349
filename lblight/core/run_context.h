// What a long-running library call needs from whoever runs it, in one value passed down the call
// chain: a flag that cancels it, the host threads it may use, and where its progress lines go.
#pragma once

#include <atomic>
#include <functional>
#include <string>

#include "lblight/core/error.h"

namespace lblight {

struct RunContext {
  // Set by a signal handler (the CLI's SIGINT/SIGTERM); once set, loading, voxelising, solving
  // and writing stop at their next check with Error(Cancelled). Null never cancels.
  const std::atomic<bool>* cancel = nullptr;
  // Host threads for host-side work (voxelising, encoding): 0 = all cores.
  int threads = 0;
  // Progress lines of long phases (report's references and runs); none when empty.
  std::function<void(const std::string&)> progress;

  void check_cancelled() const { throw_if_cancelled(cancel); }
  bool cancelled() const { return cancel && cancel->load(std::memory_order_relaxed); }
  void report(const std::string& line) const {
    if (progress) progress(line);
  }
};

}  // namespace lblight
