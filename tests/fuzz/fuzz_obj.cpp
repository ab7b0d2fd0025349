// libFuzzer target for the OBJ reader (lblight/mesh/obj_reader.cpp): any byte string must read
// as a mesh whose faces index its vertices, or be refused with lblight::Error(InvalidInput).
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "lblight/core/error.h"
#include "lblight/mesh/obj_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  try {
    const lblight::TriangleMesh m = lblight::parse_obj(in, "fuzz.obj");
    for (const auto& t : m.triangles)
      for (auto v : t)
        if (v >= m.vertices.size()) __builtin_trap();
    if (m.triangle_part.size() != m.triangles.size()) __builtin_trap();
    for (auto p : m.triangle_part)
      if (p >= m.parts.size()) __builtin_trap();
  } catch (const lblight::Error& e) {
    if (e.category() != lblight::ErrorCategory::InvalidInput) __builtin_trap();
  }
  return 0;
}
