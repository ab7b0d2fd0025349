// Runs the GPU tests, or reports them skipped (exit code 77, ctest's SKIP_RETURN_CODE) with the
// reason when this machine has no usable GPU.
#define CATCH_CONFIG_RUNNER
#include <catch2/catch.hpp>

#include <cstdio>
#include <filesystem>

#include "backends/registry.h"

int main(int argc, char** argv) {
  const std::string why = lblight::gpu_unavailable_reason();
  if (!why.empty()) {
    // A GPU the runtime cannot use (old driver, no code for its architecture) is a failure, not a
    // skip: skipping would pass the suite while `--backend auto` quietly runs on the CPU.
    if (std::filesystem::exists("/dev/nvidia0")) {
      std::printf("FAILED: /dev/nvidia0 is present but the GPU is unusable: %s\n", why.c_str());
      return 1;
    }
    std::printf("SKIPPED: GPU tests need a usable GPU: %s\n", why.c_str());
    return 77;
  }
  return Catch::Session().run(argc, argv);
}
