// libFuzzer target for the manifest reader that compare and inspect use
// (lblight/pipeline/manifest.cpp): any byte string must be refused with
// lblight::Error(InvalidInput), or parse into a manifest whose checked fields have their types,
// and no file name it holds may lead outside the output folder.
#include <cstddef>
#include <cstdint>
#include <string>

#include "lblight/core/error.h"
#include "lblight/pipeline/manifest.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const nlohmann::json m =
        lblight::parse_manifest(std::string(reinterpret_cast<const char*>(data), size), "fuzz/manifest.json");
    for (const auto& model : m.at("models")) {
      if (!model.at("name").is_string()) __builtin_trap();
      for (const auto& s : model.at("solutions"))
        if (!s.at("grid").is_string()) __builtin_trap();
      if (model.at("file").is_string()) {
        try {
          const auto p = lblight::manifest_file("/nonexistent-lblight-output", model["file"], "/models/0/file");
          if (p.parent_path() != "/nonexistent-lblight-output") __builtin_trap();
        } catch (const lblight::Error& e) {
          if (e.category() != lblight::ErrorCategory::InvalidInput) __builtin_trap();
        }
      }
    }
  } catch (const lblight::Error& e) {
    if (e.category() != lblight::ErrorCategory::InvalidInput) __builtin_trap();
  }
  return 0;
}
