#include "lblight/core/serial_worker.h"

namespace lblight {

SerialWorker::SerialWorker(bool background) : background_(background) {
  if (background_) thread_ = std::thread([this] { run(); });
}

SerialWorker::~SerialWorker() {
  if (!background_) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
    tasks_.clear();
  }
  wake_.notify_all();
  thread_.join();
}

void SerialWorker::rethrow_failure() {
  if (failure_) std::rethrow_exception(failure_);  // sticky: the output is unusable after one
}

void SerialWorker::post(std::function<void()> task) {
  if (!background_) {
    task();
    return;
  }
  {
    std::unique_lock<std::mutex> lock(mutex_);
    room_.wait(lock, [this] { return tasks_.size() < kMaxQueued || failure_; });
    rethrow_failure();
    tasks_.push_back(std::move(task));
  }
  wake_.notify_one();
}

void SerialWorker::wait() {
  if (!background_) return;
  std::unique_lock<std::mutex> lock(mutex_);
  idle_.wait(lock, [this] { return tasks_.empty() && !busy_; });
  rethrow_failure();
}

void SerialWorker::run() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    wake_.wait(lock, [this] { return stopping_ || !tasks_.empty(); });
    if (stopping_) return;
    std::function<void()> task = std::move(tasks_.front());
    tasks_.pop_front();
    busy_ = true;
    lock.unlock();
    room_.notify_all();
    std::exception_ptr failed;
    try {
      task();
    } catch (...) {
      failed = std::current_exception();
    }
    task = nullptr;  // release what the task held (a solution's totals) before reporting idle
    lock.lock();
    busy_ = false;
    if (failed && !failure_) failure_ = failed;
    if (failure_) {
      tasks_.clear();  // later tasks build on the failed one (same file)
      room_.notify_all();
    }
    if (tasks_.empty()) idle_.notify_all();
  }
}

}  // namespace lblight
