#!/usr/bin/env bash
# One command from a fresh Debian machine: install what is missing, build, then
#   bootstrap.sh bake   bake the shipped default scene into out/default
#   bootstrap.sh test   run the whole test suite through ctest, then the fast set under ASan and
#                       UBSan and every fuzzer (scripts/sanitize.sh)
# Each stage prints its wall time ("stage <name>: <seconds> s"), and a summary at the end: CI has
# 2 cores and must come back well inside 30 minutes (docs/architecture.md, "CI").
set -euo pipefail
cd "$(dirname "$0")/.."
mode="${1:-bake}"
case "$mode" in bake|test) ;; *) echo "usage: $0 bake|test" >&2; exit 2 ;; esac
source scripts/stage-timer.sh

stage setup scripts/setup-debian.sh
jobs="$(nproc 2>/dev/null || echo 2)"
stage configure cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
stage build cmake --build build -j"$jobs"

if [ "$mode" = bake ]; then
  stage bake ./build/lblight bake configs/default.json -o out/default
  ./build/lblight inspect out/default
else
  stage suite ctest --test-dir build --output-on-failure -j"$jobs"
  scripts/sanitize.sh build-asan   # the fast set under ASan + UBSan, then every fuzzer (its own stages)
fi
stage_summary
