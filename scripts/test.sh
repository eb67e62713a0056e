#!/usr/bin/env bash
# The README's second command: install, build, run every test.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
bash scripts/setup.sh
bash scripts/build.sh
if [ ! -d ../shared/data ]; then
  echo "note: ../shared/data is absent; tests that need external models and clips will skip" >&2
fi
ctest --test-dir build --output-on-failure -j "$(nproc)" --timeout 600
