// Facts about the host machine used for planning and reports.
#pragma once

#include <cstddef>
#include <string>

namespace lblight {

std::size_t host_available_memory_bytes();  // MemAvailable, or 0 when unknown
std::string host_cpu_model();
// The L3 that CPU 0 shares with its neighbours (sysfs; glibc's sysconf reports the whole
// package's L3 on AMD: 384 MiB on a 12-CCD EPYC, of which a core reaches 32 MiB); 32 MiB when
// unknown.
std::size_t host_last_level_cache_bytes();

}  // namespace lblight
