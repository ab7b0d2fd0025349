// Runs tasks one at a time, in the order posted: on a background thread, or at once on the
// caller's thread. The bake posts its output work here so that, on a GPU, writing a solution
// overlaps with solving the next; on the CPU backend the solver owns every core, so the work runs
// inline (a busy extra thread would stall the solver's static OpenMP schedule).
#pragma once

#include <condition_variable>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>

namespace lblight {

class SerialWorker {
 public:
  explicit SerialWorker(bool background);
  SerialWorker(const SerialWorker&) = delete;
  SerialWorker& operator=(const SerialWorker&) = delete;
  // Drops tasks not started and waits for the running one (an abandoned bake: its output folder
  // is about to be removed).
  ~SerialWorker();

  // Queues `task`; inline mode runs it now. Waits while kMaxQueued tasks are waiting (each holds
  // a solution's totals: a solver faster than its output must not fill the host's memory).
  // Rethrows a failure of an earlier task, so a bake stops at its next solution instead of
  // solving on for nothing.
  void post(std::function<void()> task);
  static constexpr std::size_t kMaxQueued = 4;
  // Waits until every posted task has run; rethrows the first failure.
  void wait();
  bool background() const { return background_; }

 private:
  void run();
  void rethrow_failure();

  const bool background_;
  std::mutex mutex_;
  std::condition_variable wake_, idle_, room_;
  std::deque<std::function<void()>> tasks_;
  bool busy_ = false, stopping_ = false;
  std::exception_ptr failure_;
  std::thread thread_;
};

}  // namespace lblight
