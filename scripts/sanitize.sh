#!/usr/bin/env bash
# The sanitizer build: lblight, its backends and tests compiled with clang, AddressSanitizer and
# UndefinedBehaviorSanitizer (and libFuzzer's coverage), then the fast test set under them and
# every fuzzer for LBLIGHT_FUZZ_SECONDS (default 30) each. Run by `bootstrap.sh test` after the
# main suite; on its own: scripts/sanitize.sh [build-dir]. Skipped, saying so, without clang.
set -euo pipefail
cd "$(dirname "$0")/.."
dir="${1:-build-asan}"
clang=""
for c in clang++-14 clang++-15 clang++; do command -v "$c" >/dev/null && { clang="$c"; break; }; done
if [ -z "$clang" ]; then
  echo "sanitize: SKIPPED: no clang++ (Debian's clang-14) for the ASan/UBSan build and the fuzzers"
  exit 0
fi
source scripts/stage-timer.sh
jobs="$(nproc 2>/dev/null || echo 2)"
# -O1 with line tables only: the sanitizers' usual level, a third cheaper to compile than -O2 -g
# (docs/architecture.md, "CI"); the stack traces keep file and line.
stage asan-configure cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER="$clang" -DLBLIGHT_CUDA=OFF \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -gline-tables-only -DNDEBUG" \
  -DLBLIGHT_SANITIZE=ON -DLBLIGHT_FUZZERS=ON -DLBLIGHT_FUZZ_SECONDS="${LBLIGHT_FUZZ_SECONDS:-30}" >/dev/null
stage asan-build cmake --build "$dir" -j"$jobs"
# Leaks at exit in third-party singletons are not findings here; every other report is fatal.
export ASAN_OPTIONS="detect_leaks=0:abort_on_error=1:allocator_may_return_null=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
stage asan-tests ctest --test-dir "$dir" --output-on-failure -j"$jobs" -L fast
stage fuzzers ctest --test-dir "$dir" --output-on-failure -j"$jobs" -L fuzz
