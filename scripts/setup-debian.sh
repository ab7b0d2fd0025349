#!/usr/bin/env bash
# Installs lblight's build dependencies from Debian 12 packages, only those that are missing.
# Runs apt-get directly as root, through sudo otherwise.
set -euo pipefail

packages=(
  build-essential cmake
  libcli11-dev libopenvdb-dev libboost-iostreams-dev libopenexr-dev libtbb-dev
  libnanovdb-dev libnanovdb-tools  # .nvdb output (header-only) and nanovdb_validate for its test
  liblog4cplus-dev  # OpenVDB's logger: lblight silences OpenVDB's own warnings and reports its errors itself
  nlohmann-json3-dev libspdlog-dev catch2
  python3-openvdb   # OpenVDB's own Python reader, used by a test to reopen bake outputs
  python3-jsonschema  # an independent JSON Schema validator for the scene schema test
  clang-14 libclang-rt-14-dev libomp-14-dev  # the sanitizer build and the fuzzers (scripts/sanitize.sh)
)
# Optional: Debian's hipcc (~13 s, 66 MB download) lets the tests compile the GPU backend as HIP;
# blender (~20 s, 75 MB) runs the add-on test (tools/blender) headless; slurm-wlm and munge (~4 s,
# 3.5 MB) let the scale-out test run a one-node Slurm (scripts/local-slurm.sh, docs/scale-out.md);
# Open MPI (~8 s, 12 MB) builds the mpi backend and runs its test under mpirun.
optional=(hipcc blender slurm-wlm munge openmpi-bin libopenmpi-dev)

installed() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"; }
missing=()
for p in "${packages[@]}"; do installed "$p" || missing+=("$p"); done
missing_optional=()
for p in "${optional[@]}"; do installed "$p" || missing_optional+=("$p"); done
if ((${#missing[@]} == 0 && ${#missing_optional[@]} == 0)); then
  echo "setup: all build dependencies are installed"
  exit 0
fi

sudo=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "setup: need root or sudo to install: ${missing[*]} ${missing_optional[*]}" >&2; exit 1; }
  sudo=sudo
fi
$sudo apt-get update -qq
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}"
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
if ((${#missing_optional[@]})); then
  echo "setup: installing optional ${missing_optional[*]}"
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing_optional[@]}" ||
    echo "setup: optional packages unavailable; the HIP compile check, the Blender add-on test, the Slurm test or the MPI test will be skipped"
fi
