#include "lblight/core/isolated_call.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <exception>
#include <fstream>
#include <sstream>

namespace lblight {

namespace {

// A "Vm...:" field of /proc/self/status in bytes, 0 when absent. Line by line: the first line
// ("Name:\tlblight") is not a number, and reading it as one ended the search before VmSize (the
// memory cap of the isolated reader was never set).
std::size_t own_status_bytes(const std::string& field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(field, 0) != 0) continue;
    std::istringstream values(line.substr(field.size()));
    std::size_t kb = 0;
    return values >> kb ? kb * 1024 : 0;
  }
  return 0;
}

// AddressSanitizer reserves terabytes of address space: a limit on it would stop everything.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kAddressSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kAddressSanitizer = true;
#else
constexpr bool kAddressSanitizer = false;
#endif
#else
constexpr bool kAddressSanitizer = false;
#endif

std::mutex& fork_mutex() {
  static std::mutex m;
  return m;
}

}  // namespace

std::unique_lock<std::mutex> hold_forks() { return std::unique_lock<std::mutex>(fork_mutex()); }

IsolatedOutcome run_isolated(const std::function<void()>& work, double timeout_seconds, const RunContext& ctx,
                             std::size_t memory_bytes) {
  // Limits on what the child adds: its address space (a backstop) and its data (private writable
  // memory: what reading allocates; the address space also holds reservations that never use memory).
  const std::size_t inherited = own_status_bytes("VmSize:"), inherited_data = own_status_bytes("VmData:");
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) throw_io(std::string("cannot create a pipe: ") + std::strerror(errno));
  std::unique_lock<std::mutex> no_loading(fork_mutex());
  const pid_t pid = ::fork();
  if (pid > 0) no_loading.unlock();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    throw_io(std::string("cannot start a child process: ") + std::strerror(errno));
  }
  if (pid == 0) {  // the child: run, report, and leave without unwinding the parent's state
    ::close(fds[0]);
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);  // never outlive this process
    if (memory_bytes > 0 && inherited > 0 && !kAddressSanitizer) {
      struct rlimit r {};
      r.rlim_cur = r.rlim_max = static_cast<rlim_t>(inherited + memory_bytes);
      ::setrlimit(RLIMIT_AS, &r);
      if (inherited_data > 0) {
        r.rlim_cur = r.rlim_max = static_cast<rlim_t>(inherited_data + memory_bytes);
        ::setrlimit(RLIMIT_DATA, &r);
      }
    }
    int code = 0;
    std::string message;
    try {
      work();
    } catch (const std::exception& e) {
      code = 3;
      message = e.what();
    } catch (...) {
      code = 3;
      message = "unknown exception";
    }
    if (!message.empty()) {
      ssize_t ignored = ::write(fds[1], message.data(), message.size());
      (void)ignored;
    }
    ::_exit(code);
  }
  ::close(fds[1]);
  IsolatedOutcome out;
  std::string message;
  const auto t0 = std::chrono::steady_clock::now();
  int status = 0;
  bool done = false, open = true;
  while (!done) {
    if (open) {  // collect what the child writes (its exception message) as it comes
      pollfd p{fds[0], POLLIN, 0};
      if (::poll(&p, 1, 50) > 0) {
        char buf[4096];
        const ssize_t n = ::read(fds[0], buf, sizeof buf);
        if (n > 0) message.append(buf, static_cast<std::size_t>(n));
        else if (n == 0) open = false;
      }
    } else {
      ::usleep(20000);
    }
    const pid_t r = ::waitpid(pid, &status, WNOHANG);
    if (r == pid) done = true;
    else if (r < 0 && errno != EINTR) done = true;
    if (done) break;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (ctx.cancelled() || elapsed > timeout_seconds) {
      ::kill(pid, SIGKILL);
      while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
      }
      ::close(fds[0]);
      out.kind = ctx.cancelled() ? IsolatedOutcome::Kind::Cancelled : IsolatedOutcome::Kind::TimedOut;
      out.message = std::to_string(static_cast<int>(timeout_seconds)) + " s";
      return out;
    }
  }
  for (char buf[4096];;) {  // the rest of the message
    const ssize_t n = ::read(fds[0], buf, sizeof buf);
    if (n <= 0) break;
    message.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fds[0]);
  if (WIFSIGNALED(status)) {
    out.kind = IsolatedOutcome::Kind::Crashed;
    out.message = std::string("signal ") + std::to_string(WTERMSIG(status)) + " (" + ::strsignal(WTERMSIG(status)) + ")";
  } else if (WIFEXITED(status) && WEXITSTATUS(status) != 0) {
    out.kind = WEXITSTATUS(status) == 3 ? IsolatedOutcome::Kind::Threw : IsolatedOutcome::Kind::Crashed;
    out.message = WEXITSTATUS(status) == 3 ? message : "exit code " + std::to_string(WEXITSTATUS(status));
  }
  return out;
}

}  // namespace lblight
