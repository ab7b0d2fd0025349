// Facts about the host machine used for planning and reports.
#pragma once

#include <cstddef>
#include <string>

#include "lblight/core/error.h"

namespace lblight {

std::size_t host_available_memory_bytes();  // MemAvailable, or 0 when unknown

// What this process may still allocate: the least of MemAvailable, what its address-space and
// data limits (ulimit -v, -d) leave above what it uses, and what its cgroup's memory limit
// (memory.max, or memory.limit_in_bytes under cgroup v1, along the whole cgroup path) leaves
// above the cgroup's usage. 0 when none of them is known.
struct MemoryLimit {
  std::size_t bytes = 0;
  std::string source;  // which limit is the least ("MemAvailable", "ulimit -v", "cgroup memory.max", ...)
};
MemoryLimit host_memory_limit();

// Before an allocation that scales with the input: Error(Unavailable) at `where` unless `bytes`
// fit in nine tenths of host_memory_limit(), saying what needs them, what limits them and how to
// need less (`reduce`). Does nothing when no limit is known.
void check_host_memory(double bytes, const std::string& what, const std::string& reduce, const Location& where = {});
std::string gib(double bytes);  // "2.50 GiB"
std::string host_cpu_model();
int host_cores();  // hardware threads, at least 1
std::string utc_timestamp();  // now, "2026-11-23T13:36:05Z"
// The L3 that CPU 0 shares with its neighbours (sysfs; glibc's sysconf reports the whole
// package's L3 on AMD: 384 MiB on a 12-CCD EPYC, of which a core reaches 32 MiB); 32 MiB when
// unknown.
std::size_t host_last_level_cache_bytes();

}  // namespace lblight
