// libFuzzer target for the .vdb density loader (lblight/io/vdb_io.cpp, read_vdb_density): any
// file must load as a dense density grid within the documented limits, or be refused with
// lblight::Error: InvalidInput for a damaged or unsuitable file, Unavailable when it needs more
// memory than the process may use. The bytes go through a file because OpenVDB reads files.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>

#include "lblight/core/error.h"
#include "lblight/io/vdb_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // A new name for every input: lblight probes each file once per path, size and time.
  static std::string file;
  static unsigned long counter = 0;
  if (!file.empty()) std::remove(file.c_str());
  file = "/tmp/lblight-fuzz-" + std::to_string(::getpid()) + "-" + std::to_string(counter++) + ".vdb";
  {
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  try {
    const lblight::ModelGrid g = lblight::read_vdb_density(file, "density", "brown", {});
    if (g.density.size() != g.dims.count() || g.material.size() != g.dims.count()) __builtin_trap();
  } catch (const lblight::Error& e) {
    if (e.category() != lblight::ErrorCategory::InvalidInput && e.category() != lblight::ErrorCategory::Unavailable)
      __builtin_trap();
  }
  return 0;
}
