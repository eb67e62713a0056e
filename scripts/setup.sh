#!/usr/bin/env bash
# Installs what bodybuilder needs on Debian 12: compilers, libraries (Debian packages only) and three test
# tools, the Khronos glTF validator, gltfpack and UPNG.js (npm, into tools/node_modules). Safe to run again; it skips
# what is there.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi

PKGS=(
  build-essential cmake ninja-build ccache pkg-config git
  libopenmesh-dev libcgal-dev libgmp-dev libmpfr-dev
  libtinygltf-dev libglm-dev nlohmann-json3-dev libstb-dev libcli11-dev
  libopenvdb-dev libboost-iostreams-dev libimath-dev libtbb-dev libblosc-dev zlib1g-dev
  libmeshoptimizer-dev libwebp-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libegl-dev libgl-dev libgles-dev libegl-mesa0 libgl1-mesa-dri
  python3  # bench/flow/*.sh read the test bed's JSON reports with it (and a test runs targets_matrix.sh)
)
# Node.js and npm only when the machine has none (some images ship NodeSource's node with its own npm).
command -v npm >/dev/null 2>&1 || PKGS+=(nodejs npm)

missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}" >&2
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# The Khronos glTF validator, used by the tests on every glTF we write; gltfpack, with which the tests
# make quantized and meshopt-compressed copies of the external models for the loader; UPNG.js, with which
# they play back the animated PNGs the flow test bed writes.
if [ ! -f "$here/tools/node_modules/gltf-validator/package.json" ] || [ ! -f "$here/tools/node_modules/gltfpack/package.json" ] ||
   [ ! -f "$here/tools/node_modules/upng-js/package.json" ]; then
  echo "setup: installing gltf-validator, gltfpack and upng-js (npm)" >&2
  (cd "$here/tools" && npm install --no-audit --no-fund --silent >/dev/null)
fi
echo "setup: ok" >&2
