#include "lblight/core/system_info.h"

#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <sstream>

namespace lblight {

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

}  // namespace lblight
