#include "lblight/core/system_info.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace lblight {

std::string utc_timestamp() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::size_t host_available_memory_bytes() {
  std::ifstream in("/proc/meminfo");
  std::string key;
  std::size_t value = 0;
  std::string unit;
  while (in >> key >> value) {
    std::getline(in, unit);
    if (key == "MemAvailable:") return value * 1024;
  }
  return 0;
}

namespace {

// A "key: value kB" line of a /proc file, in bytes; 0 when absent.
std::size_t proc_kb(const char* file, const std::string& wanted) {
  std::ifstream in(file);
  std::string key;
  std::size_t value = 0;
  std::string rest;
  while (in >> key >> value) {
    std::getline(in, rest);
    if (key == wanted) return value * 1024;
  }
  return 0;
}

// A number in a cgroup file; 0 for "max", a missing file or anything unreadable.
std::size_t cgroup_value(const std::string& file) {
  std::ifstream in(file);
  std::string text;
  if (!(in >> text) || text == "max") return 0;
  const unsigned long long v = std::strtoull(text.c_str(), nullptr, 10);
  return v >= (1ull << 62) ? 0 : static_cast<std::size_t>(v);  // v1 writes ~2^63 for "no limit"
}

// The least room (limit - usage) along this process's cgroup path, for cgroup v2 and v1.
std::size_t cgroup_room() {
  std::ifstream in("/proc/self/cgroup");
  std::string line;
  std::size_t best = 0;
  const auto consider = [&](const std::string& limit_file, const std::string& usage_file) {
    const std::size_t limit = cgroup_value(limit_file);
    if (limit == 0) return;
    const std::size_t used = cgroup_value(usage_file);
    const std::size_t room = used < limit ? limit - used : 0;
    if (best == 0 || room < best) best = room == 0 ? 1 : room;
  };
  while (std::getline(in, line)) {
    const auto c1 = line.find(':'), c2 = line.find(':', c1 + 1);
    if (c1 == std::string::npos || c2 == std::string::npos) continue;
    const std::string controllers = line.substr(c1 + 1, c2 - c1 - 1);
    std::string path = line.substr(c2 + 1);
    const bool v2 = controllers.empty(), v1 = controllers == "memory";
    if (!v2 && !v1) continue;
    for (;;) {  // the limit of every cgroup on the way up counts
      for (const std::string& root : v2 ? std::vector<std::string>{"/sys/fs/cgroup", "/sys/fs/cgroup/unified"}
                                       : std::vector<std::string>{"/sys/fs/cgroup/memory"}) {
        const std::string dir = root + (path == "/" ? "" : path);
        if (v2) consider(dir + "/memory.max", dir + "/memory.current");
        else consider(dir + "/memory.limit_in_bytes", dir + "/memory.usage_in_bytes");
      }
      if (path.empty() || path == "/") break;
      const auto slash = path.rfind('/');
      path = slash == 0 || slash == std::string::npos ? "/" : path.substr(0, slash);
    }
  }
  return best;
}

// What an rlimit leaves above `used`; 0 when unlimited.
std::size_t rlimit_room(int resource, std::size_t used) {
  struct rlimit r {};
  if (getrlimit(resource, &r) != 0 || r.rlim_cur == RLIM_INFINITY) return 0;
  const std::size_t limit = static_cast<std::size_t>(r.rlim_cur);
  return used < limit ? limit - used : 1;
}

}  // namespace

namespace {
// LBLIGHT_MEMORY_LIMIT: a budget for this process (bytes, or with a K, M, G or T suffix, powers
// of 1024), less what it holds already. 0 when unset.
std::size_t configured_room() {
  const char* text = std::getenv("LBLIGHT_MEMORY_LIMIT");
  if (!text || !*text) return 0;
  char* end = nullptr;
  errno = 0;
  double v = std::strtod(text, &end);
  const std::string unit = end ? end : "";
  const std::string units = "KMGT";
  if (unit.size() == 1 && units.find(static_cast<char>(std::toupper(unit[0]))) != std::string::npos)
    v *= std::pow(1024.0, 1.0 + static_cast<double>(units.find(static_cast<char>(std::toupper(unit[0])))));
  else if (!unit.empty())
    v = -1;
  if (errno != 0 || !(v >= 1.0) || v > 1e18)
    throw Error(ErrorCategory::InvalidInput, std::string("environment variable LBLIGHT_MEMORY_LIMIT='") + text +
                                                 "' is not a memory size; allowed: bytes such as 4000000000 or 4G, "
                                                 "512M (powers of 1024)");
  const double held = 1024.0 * static_cast<double>(proc_kb("/proc/self/status", "VmRSS:"));
  return v > held ? static_cast<std::size_t>(v - held) : std::size_t{1};
}
}  // namespace

MemoryLimit host_memory_limit() {
  MemoryLimit m;
  const auto take = [&](std::size_t bytes, const char* source) {
    if (bytes > 0 && (m.bytes == 0 || bytes < m.bytes)) {
      m.bytes = bytes;
      m.source = source;
    }
  };
  take(host_available_memory_bytes(), "MemAvailable");
  take(rlimit_room(RLIMIT_AS, proc_kb("/proc/self/status", "VmSize:")), "the address-space limit (ulimit -v)");
  take(rlimit_room(RLIMIT_DATA, proc_kb("/proc/self/status", "VmData:")), "the data limit (ulimit -d)");
  take(cgroup_room(), "the cgroup memory limit");
  take(configured_room(), "LBLIGHT_MEMORY_LIMIT");
  return m;
}

std::string gib(double bytes) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.2f GiB", bytes / (1024.0 * 1024.0 * 1024.0));
  return buf;
}

void check_host_memory(double bytes, const std::string& what, const std::string& reduce, const Location& where) {
  const MemoryLimit limit = host_memory_limit();
  if (limit.bytes == 0 || bytes <= 0.9 * static_cast<double>(limit.bytes)) return;
  throw Error(ErrorCategory::Unavailable,
              what + " needs " + gib(bytes) + " of memory, but this process may allocate only " +
                  gib(static_cast<double>(limit.bytes)) + " more (" + limit.source + "); " + reduce,
              where);
}

std::string host_cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) == 0) {
      const auto colon = line.find(':');
      if (colon != std::string::npos) return line.substr(colon + 2);
    }
  }
  return "unknown CPU";
}

std::size_t host_last_level_cache_bytes() {
  for (int index = 0; index < 8; ++index) {
    const std::string dir = "/sys/devices/system/cpu/cpu0/cache/index" + std::to_string(index) + "/";
    std::ifstream level(dir + "level"), size(dir + "size");
    int l = 0;
    std::string text;
    if (!(level >> l) || !(size >> text)) break;
    if (l != 3 || text.empty()) continue;
    const char unit = text.back();
    const std::size_t n = std::strtoull(text.c_str(), nullptr, 10);
    const std::size_t scale = unit == 'K' ? 1024u : unit == 'M' ? (1u << 20) : 1u;
    if (n > 0) return n * scale;
  }
  long l3 = -1;
#ifdef _SC_LEVEL3_CACHE_SIZE
  l3 = sysconf(_SC_LEVEL3_CACHE_SIZE);
#endif
  return l3 > 0 ? static_cast<std::size_t>(l3) : (32u << 20);
}

int host_cores() { return std::max(1, static_cast<int>(std::thread::hardware_concurrency())); }

}  // namespace lblight
