#!/usr/bin/env bash
# The README's first command: install, build, run the main job on the built-in default body.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
bash scripts/setup.sh
bash scripts/build.sh
exec ./build/bin/bodybuilder demo -o out/demo "$@"
