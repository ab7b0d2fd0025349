#!/usr/bin/env bash
# Packs a CUDA build of lblight with every shared library it needs (glibc included) into one
# archive, for a GPU machine that has the NVIDIA driver but not Debian's packages (a CUDA
# container image with no OpenVDB, TBB or spdlog, and no network to install them).
#   usage: scripts/device-bundle.sh [BUILD_DIR] [OUT_DIR]    (defaults: build, .device-bundle)
# Produces OUT_DIR/lblight-bundle.tar.xz (~17 MB). On the GPU machine, from the repository root:
#   python3 -c 'import tarfile; tarfile.open(".device-bundle/lblight-bundle.tar.xz").extractall("/tmp")'
#   LBLIGHT_BUNDLE=/tmp/lblight-bundle scripts/gpu-acceptance.sh /tmp/acceptance
# bin/ holds wrappers that run the programs with the bundled libraries: with the machine's own
# glibc when it is at least the bundled one, else through the bundled dynamic loader.
set -euo pipefail
cd "$(dirname "$0")/.."
build="${1:-build}"
out="${2:-.device-bundle}"
programs=("$build/lblight" "$build/tests/lblight_gpu_tests" "$build/tools/gpu_pipeline_sim/gpu_pipeline_sim")
for p in "${programs[@]}"; do
  [ -x "$p" ] || { echo "device-bundle: $p is missing; build first (cmake --build $build)" >&2; exit 1; }
done
[ -f "$build/backends/cuda/liblblight_cuda.a" ] ||
  { echo "device-bundle: $build has no CUDA backend (nvcc not found at configure time)" >&2; exit 1; }

stage="$(mktemp -d)"
trap 'rm -rf "$stage"' EXIT
b="$stage/lblight-bundle"
mkdir -p "$b/bin" "$b/real" "$b/lib/deps" "$b/lib/glibc"
for p in "${programs[@]}"; do
  cp "$p" "$b/real/"
  # every resolved library except the driver's (it must be the machine's own)
  ldd "$p" | awk '$3 ~ /^\// { print $3 } $1 ~ /^\/.*ld-linux/ { print $1 }' | while read -r lib; do
    name="$(basename "$lib")"
    case "$name" in
      libcuda.so*|libnvidia*) ;;
      ld-linux*|libc.so*|libm.so*|libpthread.so*|libdl.so*|librt.so*) cp -L "$lib" "$b/lib/glibc/$name" ;;
      *) cp -L "$lib" "$b/lib/deps/$name" ;;
    esac
  done
done
glibc_version="$(getconf GNU_LIBC_VERSION | awk '{ print $2 }')"
echo "$glibc_version" > "$b/lib/glibc/VERSION"
for p in "${programs[@]}"; do
  name="$(basename "$p")"
  cat > "$b/bin/$name" <<EOF
#!/bin/sh
# $name from the lblight bundle (scripts/device-bundle.sh; built against glibc $glibc_version).
here="\$(cd "\$(dirname "\$0")/.." && pwd)"
mine="\$(getconf GNU_LIBC_VERSION 2>/dev/null | awk '{ print \$2 }')"
need="\$(cat "\$here/lib/glibc/VERSION")"
if [ -n "\$mine" ] && [ "\$(printf '%s\n%s\n' "\$need" "\$mine" | sort -V | head -n 1)" = "\$need" ]; then
  LD_LIBRARY_PATH="\$here/lib/deps\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}" exec "\$here/real/$name" "\$@"
fi
exec "\$here/lib/glibc/ld-linux-x86-64.so.2" --library-path \\
  "\$here/lib/glibc:\$here/lib/deps\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}:/usr/lib/x86_64-linux-gnu:/usr/local/nvidia/lib64:/usr/lib64" \\
  "\$here/real/$name" "\$@"
EOF
  chmod +x "$b/bin/$name"
done
git rev-parse --short HEAD > "$b/COMMIT" 2> /dev/null || echo unknown > "$b/COMMIT"
mkdir -p "$out"
tar -C "$stage" -cJf "$out/lblight-bundle.tar.xz" lblight-bundle
echo "device-bundle: $out/lblight-bundle.tar.xz ($(du -h "$out/lblight-bundle.tar.xz" | cut -f1), commit $(cat "$b/COMMIT"), glibc $glibc_version)"
