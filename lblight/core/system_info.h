// Facts about the host machine used for planning and reports.
#pragma once

#include <cstddef>
#include <string>

namespace lblight {

std::size_t host_available_memory_bytes();  // MemAvailable, or 0 when unknown
std::string host_cpu_model();

}  // namespace lblight
