// libFuzzer target for the scene parser (lblight/scene/scene_parse.cpp): any byte string must
// parse or be refused with lblight::Error (InvalidInput, naming the file); any other exception
// (a raw JSON library error reaching the user), a crash or a hang is a finding.
#include <cstddef>
#include <cstdint>
#include <string>

#include "lblight/core/error.h"
#include "lblight/scene/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const lblight::Scene s = lblight::parse_scene(std::string(reinterpret_cast<const char*>(data), size), "fuzz.json");
    if (s.models.empty()) __builtin_trap();  // a scene that parses has a model
  } catch (const lblight::Error& e) {
    if (e.category() != lblight::ErrorCategory::InvalidInput || e.where().file != "fuzz.json") __builtin_trap();
  }
  return 0;
}
