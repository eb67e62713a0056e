#!/usr/bin/env bash
# Prepares what bench/flow/gpu_run.sh needs on a lent NVIDIA machine (the device tool), from this
# checkout's build (scripts/build.sh first): .gl/ (the GL loader packages, downloaded as .deb files
# from the Debian registry), .gpu/bin/bench_flow, .gpu/lib/ (the libraries bench_flow links beside
# the C/C++ runtime and the GL loaders) and .gpu/models/ (the default crowd, built here, and the
# shared models). Both folders are ignored through .git/info/exclude. Then, with the device tool:
#   run  command: bash bench/flow/gpu_run.sh SET...   carry: [".gl", ".gpu"]
set -euo pipefail
cd "$(dirname "$0")/../.."
B=build/bin/bench_flow
[ -x "$B" ] && [ -x build/bin/bodybuilder ] || { echo "gpu_prepare: build first (bash scripts/build.sh)" >&2; exit 1; }
SHARED=${BB_SHARED_DATA_DIR:-../shared/data}
mkdir -p .git/info
for d in /.gl/ /.gpu/; do grep -qxF "$d" .git/info/exclude 2>/dev/null || echo "$d" >>.git/info/exclude; done

# The GL loaders (the device's driver brings the rest).
if ! ls .gl/*.deb >/dev/null 2>&1; then
  mkdir -p .gl /tmp/bb_gl_lists/partial
  o=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/bb_gl_lists)
  apt-get "${o[@]}" update >/dev/null
  (cd .gl && apt-get "${o[@]}" download libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2)
fi

rm -rf .gpu
mkdir -p .gpu/bin .gpu/lib .gpu/models
cp "$B" .gpu/bin/
# Every library bench_flow links but the C/C++ runtime and the GL loaders.
ldd "$B" | awk '$3 ~ /^\// {print $3}' | while read -r lib; do
  case "$(basename "$lib")" in
    libc.so.*|libm.so.*|libstdc++.so.*|libgcc_s.so.*|libEGL.so.*|libOpenGL.so.*|libGLdispatch.so.*|libGLX.so.*|libGL.so.*) ;;
    *) cp -L "$lib" .gpu/lib/ ;;
  esac
done
# PREV=REV: also bench_flow as commit REV built it, as .gpu/bin/bench_flow_prev, for the sets that
# alternate the binary before a change with this one (a worktree and build under /tmp).
if [ -n "${PREV:-}" ]; then
  w=$(mktemp -d /tmp/bb_prev.XXXXXX)
  git worktree add -q --detach "$w" "$PREV"
  cmake -S "$w" -B "$w/build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$w/build" --target bench_flow >/dev/null
  cp "$w/build/bin/bench_flow" .gpu/bin/bench_flow_prev
  git worktree remove --force "$w"
fi
build/bin/bodybuilder build -o .gpu/models --variants 3 --no-errors >/dev/null
for m in CesiumMan.glb Fox.glb RiggedSimple.gltf SimpleSkin.gltf; do
  if [ -f "$SHARED/gltf/$m" ]; then cp "$SHARED/gltf/$m" .gpu/models/; else echo "gpu_prepare: $SHARED/gltf/$m absent, skipped" >&2; fi
done
echo "gpu_prepare: $(du -sh .gl .gpu | tr '\n' ' ')(the device tool carries at most 64 MiB)"
