#!/usr/bin/env bash
# Configures and builds bodybuilder (Release, Ninja, ccache when present) into ./build.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release ${BB_CMAKE_ARGS:-} >/dev/null
cmake --build build -j "$(nproc)"
