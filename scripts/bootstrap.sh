#!/usr/bin/env bash
# One command from a fresh Debian machine: install what is missing, build, then
#   bootstrap.sh bake   bake the shipped default scene into out/default
#   bootstrap.sh test   run the whole test suite through ctest, then the fast set under ASan and
#                       UBSan and every fuzzer (scripts/sanitize.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
mode="${1:-bake}"
case "$mode" in bake|test) ;; *) echo "usage: $0 bake|test" >&2; exit 2 ;; esac

scripts/setup-debian.sh
jobs="$(nproc 2>/dev/null || echo 2)"
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
cmake --build build -j"$jobs"

if [ "$mode" = bake ]; then
  ./build/lblight bake configs/default.json -o out/default
  ./build/lblight inspect out/default
else
  ctest --test-dir build --output-on-failure -j"$jobs"
  scripts/sanitize.sh build-asan   # the fast set under ASan + UBSan, then every fuzzer
fi
