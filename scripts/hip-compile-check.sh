#!/usr/bin/env bash
# Compiles the GPU backend, the .lbh reader's device example and the gas solver's node update in
# kernels as HIP (compile only: AMD's gfx90a, no GPU needed), proving the kernel source is written
# once for CUDA and HIP. Exit 77
# (skipped) when hipcc is not installed.
#   usage: scripts/hip-compile-check.sh [OUT.o]
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v hipcc >/dev/null; then
  echo "SKIPPED: hipcc not installed (Debian package hipcc)"
  exit 77
fi
out="${1:-$(mktemp -d)/cuda_backend_hip.o}"
hipcc --offload-arch=gfx90a -x hip -std=c++17 -Werror -I. -c backends/cuda/cuda_backend.cu -o "$out"
echo "HIP compile of backends/cuda/cuda_backend.cu for gfx90a: ok ($out)"
# The .lbh reader's device functions, through its CUDA/HIP example.
hipcc --offload-arch=gfx90a -x hip -std=c++17 -Werror -Ireaders/lbh -c readers/lbh/cuda_example.cu -o "${out%.o}_lbh_example.o"
echo "HIP compile of readers/lbh/cuda_example.cu for gfx90a: ok"
# The gas solver's per-node update (lblight/fluid/gas_node.h) in kernels.
hipcc --offload-arch=gfx90a -x hip -std=c++17 -Werror -I. -c tests/fluid/gas_kernels_compile.cu -o "${out%.o}_gas.o"
echo "HIP compile of tests/fluid/gas_kernels_compile.cu for gfx90a: ok"
