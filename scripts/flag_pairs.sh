#!/usr/bin/env bash
# Every pair of a list of `bodybuilder flow` settings (and of `render` settings on the shared models)
# on a tiny scene: each run must end with status 0 or a clear error (1, 2, or CLI11's 100-120), never
# by a signal or past its time. Not part of the test suite (about 2,900 runs, 20-40 minutes on a
# 2-core machine); the fifty-second session's run found `flow --mode impostor --scaling` aborting.
#   bash scripts/flag_pairs.sh [flow|render|both]   (build first: bash scripts/build.sh)
set -uo pipefail
cd "$(dirname "$0")/.."
what=${1:-both}
B=$(mktemp -d)/bodybuilder
cp build/bin/bodybuilder "$B"  # a copy: a rebuild during the run would break it
OUT=$(mktemp -d)
SHARED=${BB_SHARED_DATA_DIR:-../shared/data}
bad=0 runs=0
check() {  # check ARGS...: one run
  local rc
  timeout 120 "$B" "$@" >"$OUT/last.out" 2>&1
  rc=$?
  runs=$((runs + 1))
  if [ $rc -ge 124 ] || { [ $rc -gt 2 ] && { [ $rc -lt 100 ] || [ $rc -gt 120 ]; }; }; then
    bad=$((bad + 1))
    echo "status $rc: bodybuilder $*"
    tail -3 "$OUT/last.out"
  fi
}
if [ "$what" != render ]; then
  opts=("" "--mode impostor" "--mode geometry" "--posture off" "--view off" "--posture off --view off" "--posture 0 --view 0"
    "--distance-weighting" "--screen-weighting 0" "--orbit 90" "--msaa 1" "--msaa 8" "--impostor-target scene"
    "--impostor-target single" "--impostor-target adaptive" "--texels-per-pixel 2" "--texels-per-pixel 0.5"
    "--window-sizes 64" "--window-sizes 8" "--impostor-edges samples" "--impostor-edges coverage" "--impostor-edges test"
    "--impostor-edges centre" "--snapshot-lod window" "--snapshot-camera orthographic" "--animation" "--hold-poses"
    "--lods 0" "--impostor-parts" "--impostor-parts --limb-cards turn" "--relight on" "--impostor-parts --card-depth on"
    "--impostor-parts --card-depth pass" "--view-lead 0.5" "--snapshot-grid pixels" "--snapshot-grid free"
    "--snapshot-scale fill" "--snapshot-samples 4" "--impostor-taps 1" "--impostor-taps 4" "--quad-fit boxes"
    "--quad-fit coverage" "--quad-fit vertices" "--coverage-group 16" "--quad-fetch instanced" "--quad-fetch pulled" "--flush-every 0" "--flush-every 100"
    "--short-lived geometry" "--short-lived snapshot" "--planner-threads 1" "--gpu-stages" "--refresh-budget 1"
    "--refresh-ahead 0.5" "--sweep view --sweep-thresholds 0,8" "--sweep posture --sweep-thresholds 0,0.4"
    "--scaling --scaling-humans 2,5 --scaling-frames 1" "--targets" "--json")
  for ((a = 0; a < ${#opts[@]}; a++)); do
    for ((b = a; b < ${#opts[@]}; b++)); do
      # shellcheck disable=SC2086  # each setting is a list of flags
      check flow --variants 0 --humans 3 --frames 2 --warmup 1 --size 96x80 ${opts[a]} ${opts[b]} -o "$OUT/flow"
    done
  done
fi
if [ "$what" != flow ]; then
  build/bin/bodybuilder build -o "$OUT/models" --no-errors >/dev/null
  models=("$OUT/models/default.glb")
  for m in CesiumMan.glb Fox.glb RiggedSimple.gltf SimpleSkin.gltf; do
    if [ -f "$SHARED/gltf/$m" ]; then models+=("$SHARED/gltf/$m"); else echo "flag_pairs: $SHARED/gltf/$m absent, skipped"; fi
  done
  opts=("" "--mode impostor" "--time 1.3" "--time -7" "--azimuth 90" "--elevation 89" "--elevation -30" "--distance 0.5"
    "--distance 500" "--size 8x8" "--size 33x17" "--lod 0" "--lod 2" "--lod 7" "--lods 0" "--snapshot ortho" "--frames 3"
    "--frames 3 --spin 90" "--fps 1" "--json" "--clip nonesuch")
  for m in "${models[@]}"; do
    for ((a = 0; a < ${#opts[@]}; a++)); do
      for ((b = a; b < ${#opts[@]}; b++)); do
        size="--size 64x64"
        [[ "${opts[a]} ${opts[b]}" == *--size* ]] && size=""
        # shellcheck disable=SC2086
        check render "$m" ${opts[a]} ${opts[b]} $size -o "$OUT/render.png"
      done
    done
  done
fi
echo "flag_pairs: $runs runs, $bad ended by a signal or past their time"
[ $bad -eq 0 ]
