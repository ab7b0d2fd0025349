#!/usr/bin/env bash
# Issue 5's measurements on a machine with an NVIDIA GPU, in one go, for docs/performance.md:
# build with CUDA, the GPU conformance tests (and compute-sanitizer when installed), bench at
# 64/128/256 in float32 and float16 with the copy bandwidth measured in the same run (two levels
# and in place), and the complete 19 x 3 plant-128 bake timed on the GPU (float32 and float16 as
# bakes run them, in place; float32 with two levels) and on the CPU, with the GPU grids compared to
# the CPU's and in place to two levels, then compute-sanitizer when installed. Everything lands in
# OUTDIR; summary.txt has the headline figures.
# Exit 77 (skipped) when no GPU is usable.
#   usage: scripts/gpu-acceptance.sh [OUTDIR]     (default: out/gpu-acceptance)
#   SKIP_CPU_REFERENCE=1 leaves out the CPU bake and the comparison (minutes on few cores).
#   LBLIGHT_BUNDLE=DIR uses the prebuilt programs of an unpacked scripts/device-bundle.sh archive
#   instead of building (for GPU machines without Debian's packages).
#   SANITIZER_SECONDS=N caps each compute-sanitizer run (default 120).
set -uo pipefail
cd "$(dirname "$0")/.."
out="${1:-out/gpu-acceptance}"
sanitizer_seconds="${SANITIZER_SECONDS:-120}"
mkdir -p "$out"
summary="$out/summary.txt"
: > "$summary"
note() { echo "$*" | tee -a "$summary"; }
timed() {  # timed LOG command...: appends the command's stderr and its wall time to LOG
  local log="$1"; shift
  local t0 t1
  t0=$(date +%s%N)
  "$@" >> "$log" 2>&1
  local rc=$?
  t1=$(date +%s%N)
  echo "$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f", (b - a) / 1e9 }') s (exit $rc): $*" | tee -a "$log" >> "$summary"
  return $rc
}

if ! nvidia-smi > "$out/nvidia-smi.txt" 2>&1; then
  echo "SKIPPED: nvidia-smi found no usable GPU (see $out/nvidia-smi.txt)"
  exit 77
fi
note "GPU: $(nvidia-smi --query-gpu=name,memory.total,driver_version,clocks.max.memory --format=csv,noheader)"
note "CPU: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//')"
note "commit: $(git rev-parse --short HEAD 2>/dev/null || echo unknown)"

if [ -n "${LBLIGHT_BUNDLE:-}" ]; then
  note "== prebuilt bundle $LBLIGHT_BUNDLE (commit $(cat "$LBLIGHT_BUNDLE/COMMIT" 2> /dev/null))"
  exe="$LBLIGHT_BUNDLE/bin/lblight"
  gpu_tests="$LBLIGHT_BUNDLE/bin/lblight_gpu_tests"
  sim="$LBLIGHT_BUNDLE/bin/gpu_pipeline_sim"
  export LBLIGHT_EXE="$exe"  # the GPU tests run this lblight, not the path they were built with
else
  note "== build"
  if ! timed "$out/build.log" cmake -S . -B build -DCMAKE_BUILD_TYPE=Release ||
     ! timed "$out/build.log" cmake --build build -j"$(nproc)"; then
    note "build failed: $out/build.log"
    exit 1
  fi
  [ -f build/backends/cuda/liblblight_cuda.a ] || note "warning: the CUDA backend was not built (nvcc not found?)"
  exe=build/lblight
  gpu_tests=build/tests/lblight_gpu_tests
  sim=build/tools/gpu_pipeline_sim/gpu_pipeline_sim
fi
"$exe" --version > /dev/null || { note "cannot run $exe"; exit 1; }

note "== GPU conformance (CUDA vs OpenMP to 1e-5, determinism, float16 error, bake grids)"
timed "$out/gpu_conformance.log" "$gpu_tests" --durations yes
grep -E "^(test cases|All tests passed)" "$out/gpu_conformance.log" | tail -n 1 >> "$summary"

note "== bench (updates/s and fraction of the copy bandwidth measured in the same run)"
timed "$out/bench.log" "$exe" bench --backend cuda --size 64 128 256 --precision float32 float16
"$exe" bench --backend cuda --size 64 128 256 --precision float32 float16 --json > "$out/bench.json" 2>> "$out/bench.log"
timed "$out/bench.log" "$exe" bench --backend cuda --size 128 --systems 3 --precision float32 float16
timed "$out/bench.log" "$exe" bench --backend cuda --size 64 --systems 15 --precision float32
grep -E "^(measured copy|[0-9]+x[0-9]+x[0-9]+ )" "$out/bench.log" >> "$summary"

note "== plant-128: complete 19 x 3 bake, 260 steps, including voxelisation and I/O"
for run in 1 2 3; do
  timed "$out/bake-gpu-f32.log" "$exe" bake configs/plant-128.json --backend cuda -o "$out/plant-128-gpu"
done
grep -h "tree.vdb:" "$out/bake-gpu-f32.log" | tail -n 1 >> "$summary"
for run in 1 2; do
  timed "$out/bake-gpu-f16.log" "$exe" bake configs/plant-128.json --backend cuda --precision float16 \
    -o "$out/plant-128-gpu-f16"
done
# Bakes on the GPU update the state in place (one level, AA pattern); two levels must give the same bits.
note "== plant-128 on the GPU with two levels of state: the same bits as in place"
timed "$out/bake-gpu-two-levels.log" "$exe" bake configs/plant-128.json --backend cuda --state two-levels \
  -o "$out/plant-128-gpu-two-levels"
grep -h "tree.vdb:" "$out/bake-gpu-two-levels.log" | tail -n 1 >> "$summary"
"$exe" compare "$out/plant-128-gpu" "$out/plant-128-gpu-two-levels" --tolerance 0 | tail -n 1 | tee -a "$summary"

if [ "${SKIP_CPU_REFERENCE:-0}" != 1 ]; then
  note "== plant-128 on the CPU (OpenMP, $(nproc) threads) and the GPU grids against it"
  timed "$out/bake-cpu.log" "$exe" bake configs/plant-128.json --backend cpu -o "$out/plant-128-cpu"
  for gpu in plant-128-gpu plant-128-gpu-f16; do
    note "$gpu against the CPU bake:"
    "$exe" compare "$out/plant-128-cpu" "$out/$gpu" > "$out/compare-$gpu.txt"
    tail -n 1 "$out/compare-$gpu.txt" | tee -a "$summary"
  done
  # The host-side model (docs/performance.md) with this GPU's measured copy bandwidth and 128^3
  # float32 fraction, to set against the timed bakes above.
  read -r gbs frac < <(python3 -c '
import json, sys
b = json.load(open(sys.argv[1]))
r = [r for r in b["runs"] if r["lattice"][0] == 128 and r["precision"] == "float32"][0]
print(b["copy_bandwidth_gbs"], r["fraction_of_copy_bandwidth"])' "$out/bench.json" 2> /dev/null) || true
  if [ -n "${gbs:-}" ] && [ -x "$sim" ]; then
    note "simulated device at the measured ${gbs} GB/s x ${frac} (start-up 0.5 s assumed):"
    "$sim" configs/plant-128.json --reference "$out/plant-128-cpu/tree.vdb" \
      --bandwidth "$gbs" --fraction "$frac" -o "$out/plant-128-sim" 2> "$out/sim.log" | grep wall | tee -a "$summary"
  fi
fi
# Last, as they are the slowest and the least likely to change the figures above: the memory and
# race checkers on the fast tests, each capped (one Catch2 spec: a second argument would be joined
# to the first; the bake test is left out, so no lblight child is followed into).
if command -v compute-sanitizer > /dev/null && [ -x "$gpu_tests" ]; then
  note "== compute-sanitizer on the fast GPU tests (memcheck, racecheck; at most $sanitizer_seconds s each)"
  for tool in memcheck racecheck; do
    timed "$out/$tool.log" timeout "$sanitizer_seconds" compute-sanitizer --tool "$tool" --error-exitcode 3 \
      "$gpu_tests" "[conformance]~[slow],float16 storage*"
    grep -E "ERROR SUMMARY|RACECHECK SUMMARY" "$out/$tool.log" | tail -n 1 >> "$summary"
  done
fi
note "== done: $out"
