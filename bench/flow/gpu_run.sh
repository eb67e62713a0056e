#!/usr/bin/env bash
# The flow test bed on a lent NVIDIA machine (the device tool): the runtime-only bench_flow with
# the same flags as `bodybuilder flow`. Prepare here with `bash bench/flow/gpu_prepare.sh`, which makes:
#   .gl/  the GL loader packages (libegl1 libglvnd0 libopengl0 libgl1 libglx0 ...), .deb files
#   .gpu/bin/bench_flow, .gpu/lib/ (the libraries `ldd build/bin/bench_flow` names beside libc, libm,
#   libstdc++, libgcc_s and the GL loaders: libtinygltf.so.2d, libmeshoptimizer.so.2d, libwebp.so.7,
#   libstb.so.0), .gpu/models/ (the default crowd below, and CesiumMan.glb, Fox.glb, RiggedSimple.gltf,
#   SimpleSkin.gltf copied from ../shared/data/gltf)
# and run `bash bench/flow/gpu_run.sh SET...` with .gl and .gpu carried; results go to $OUT.
set -uo pipefail
if command -v nvidia-smi >/dev/null; then  # only there: the loaders go into /
  for f in .gl/*.deb; do dpkg -x "$f" /; done
  ldconfig
fi
export LD_LIBRARY_PATH="$PWD/.gpu/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export __EGL_VENDOR_LIBRARY_FILENAMES=${__EGL_VENDOR_LIBRARY_FILENAMES:-/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json}
[ -f "$__EGL_VENDOR_LIBRARY_FILENAMES" ] || unset __EGL_VENDOR_LIBRARY_FILENAMES
OUT=${OUT:-/tmp/gpu_out}
R=/tmp/gpu_results
mkdir -p "$OUT" "$R"
B=.gpu/bin/bench_flow
M=.gpu/models
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.mem --format=csv 2>&1 | tee "$R/gpu.txt"
echo "cpus: $(nproc), cgroup cpu.max: $(cat /sys/fs/cgroup/cpu.max 2>/dev/null || echo none), $(grep -m1 'model name' /proc/cpuinfo)" | tee -a "$R/gpu.txt"
# The default crowd of `bodybuilder flow`: the built-in body and three seeded variants, built here with
# `bodybuilder build -o .gpu/models --variants 3 --no-errors`.
C4="--model $M/default.glb --model $M/default_v1.glb --model $M/default_v2.glb --model $M/default_v3.glb"
T_END=$((SECONDS + ${GPU_RUN_SECONDS:-540}))  # no new run starts after this (the device's call limit)
# flow NAME ARGS...: one run, its JSON report as $R/NAME.json, a line of figures on stdout.
flow() {
  local name=$1; shift
  local t0=$SECONDS
  if [ $SECONDS -ge $T_END ]; then echo "$name skipped (time)"; return; fi
  if timeout "${FLOW_TIMEOUT:-300}" "$B" flow "$@" -o "$R/$name" --json >"$R/$name.json" 2>"$R/$name.err"; then
    python3 - "$R/$name.json" "$name" $((SECONDS - t0)) <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
def line(x, tag):
    return f"{tag:28s} geo {x.get('geometry_ms',0):8.3f} imp {x.get('impostor_ms',0):8.3f} x{1/x['ratio'] if x.get('ratio') else 0:6.2f} f {x.get('refresh_fraction',0):.3f} psnr {x.get('psnr_db',0):5.1f} ssim {x.get('ssim',0):.3f}"
print(line(r, sys.argv[2]) + f"  ({sys.argv[3]} s) {r.get('device','')[:40]}")
spr = r.get('frame_ms_spread')
if spr:
    print("  spread " + " | ".join(f"{k} p95 {d['p95']:.3f} max {d['max']:.3f} sd {d['sd']:.3f}" for k, d in spr.items()) + f" | snapshots_max {r.get('snapshots_max')}")
sp = r.get('frame_ms_split')
if sp:
    print("  split " + " | ".join(f"{k} " + "/".join(f"{v:.3f}" for v in d.values()) for k, d in sp.items() if isinstance(d, dict)))
gs = r.get('gpu_ms_stages')
if gs and 'impostor' in gs:
    gi = gs['impostor']
    print(f"  gpu: geometry {gs['geometry']['geometry']:.3f} | impostor snapshots {gi['snapshots']:.3f} coverage {gi['coverage']:.3f} quads {gi['impostors']:.3f} | coverage_group {r.get('coverage_group')}")
for s in r.get('sweep', []):
    print(line(s, "  %s" % s.get('threshold', s.get('view_deg', s.get('posture')))))
for t in r.get('targets', []):
    met = {True: 'yes', False: 'NO', None: '-'}[t.get('met')]
    print(f"  target [{met}] {t['target'][:60]}: {t['measured']}")
for s in r.get('scaling', []):
    sp = s.get('frame_ms_split', {})
    g, i = sp.get('geometry', {}), sp.get('impostor', {})
    print(f"  humans {s['humans']:6d} geo {s['geometry_ms']:9.3f} imp {s['impostor_ms']:8.3f} x{s['geometry_ms']/max(s['impostor_ms'],1e-9):6.2f} f {s.get('refresh_fraction',0):.3f}"
          f" | geo plan/submit/finish {g.get('plan',0):.2f}/{g.get('submit',0):.2f}/{g.get('finish',0):.2f} imp {i.get('plan',0):.2f}/{i.get('submit',0):.2f}/{i.get('finish',0):.2f}")
    gs = s.get('gpu_ms_stages')
    if gs:
        gi = gs['impostor']
        print(f"      gpu: geometry {gs['geometry']['geometry']:.3f} | impostor snapshots {gi['snapshots']:.3f} coverage {gi['coverage']:.3f} quads {gi['impostors']:.3f}")
PY
  else
    echo "$name FAILED: $(tail -3 "$R/$name.err")"
  fi
}
set_smoke() {
  flow smoke --model $M/default.glb --frames 5
}
set_scale() {
  flow scaling --model $M/default.glb --frames 2 --gpu-stages --scaling --scaling-humans 20,1000,10000 --scaling-frames 5
  flow scaling_view --model $M/default.glb --frames 2 --gpu-stages --posture off --scaling --scaling-humans 1000,10000 --scaling-frames 5
  flow scaling_dw --model $M/default.glb --frames 2 --gpu-stages --distance-weighting --scaling --scaling-humans 20,1000,10000 --scaling-frames 5
  flow scaling_cesium --model $M/CesiumMan.glb --frames 2 --gpu-stages --scaling --scaling-humans 1000,10000 --scaling-frames 5
  flow main_stages --model $M/default.glb --frames 60 --gpu-stages
}
set_threads() {
  for t in 1 0; do
    flow scaling_t$t --model $M/default.glb --frames 2 --gpu-stages --planner-threads $t --scaling --scaling-humans 1000,10000 --scaling-frames 8
    flow scaling_dw_t$t --model $M/default.glb --frames 2 --gpu-stages --planner-threads $t --distance-weighting --scaling --scaling-humans 1000,10000 --scaling-frames 8
    flow scaling_cesium_dw_t$t --model $M/CesiumMan.glb --frames 2 --gpu-stages --planner-threads $t --distance-weighting --scaling --scaling-humans 10000 --scaling-frames 8
  done
  flow scaling_full --model $M/default.glb --frames 2 --scaling --scaling-humans 20,100,500,1000,2000,5000,10000 --scaling-frames 8
  flow scaling_full_dw --model $M/default.glb --frames 2 --distance-weighting --scaling --scaling-humans 20,100,500,1000,2000,5000,10000 --scaling-frames 8
}
set_main() {
  flow smoke --model $M/default.glb --frames 5
  flow main --model $M/default.glb --frames 120
  flow worst --model $M/default.glb --frames 60 --posture 0 --view 0
  flow sweep_view --model $M/default.glb --frames 60 --sweep view
  flow sweep_posture --model $M/default.glb --frames 60 --sweep posture
  flow scaling --model $M/default.glb --frames 2 --scaling --scaling-humans 20,100,1000,2000,5000,10000 --scaling-frames 5
  flow fox_view --model $M/Fox.glb --frames 40 --sweep view
  flow cesium_view --model $M/CesiumMan.glb --frames 40 --sweep view
  flow msaa1_view --model $M/default.glb --frames 40 --sweep view --msaa 1
  flow parts_view --model $M/default.glb --frames 40 --sweep view --impostor-parts
  flow parts_quality_view --model $M/default.glb --frames 40 --sweep view --impostor-parts --texels-per-pixel 2 --impostor-edges blend
  flow exact_0 --model $M/default.glb --frames 40 --posture off --view 0 --snapshot-grid pixels --snapshot-samples 4 --impostor-edges blend
  flow exact_8 --model $M/default.glb --frames 40 --posture off --view 8 --snapshot-grid pixels --snapshot-samples 4 --impostor-edges blend
  flow budget --model $M/default.glb --frames 60 --humans 200 --orbit 30 --refresh-budget 30
  flow nobudget --model $M/default.glb --frames 60 --humans 200 --orbit 30
}
# Part cards at the best quality (28 dB at 8 degrees on llvmpipe, where it is no faster than
# geometry): does a GPU, where fill is cheap, give it the paper's speed as well? At 20 humans and at
# crowd sizes where geometry costs the GPU more than the fixed frame overhead.
set_quality() {
  local q="--posture off --impostor-parts --texels-per-pixel 2 --impostor-edges blend"
  for v in 5 8 17; do
    flow quality_on_$v --model $M/default.glb --frames 120 --view $v $q --card-depth on
    flow quality_pass_$v --model $M/default.glb --frames 120 --view $v $q --card-depth pass
  done
  flow parts_8 --model $M/default.glb --frames 120 --view 8 --posture off --impostor-parts
  for n in 200 1000; do
    flow quality_pass_8_h$n --model $M/default.glb --frames 30 --humans $n --view 8 $q --card-depth pass --gpu-stages
  done
  flow scaling_sw --model $M/default.glb --frames 2 --scaling --scaling-humans 20,1000,10000 --scaling-frames 5
}
# Seventeenth session: the present code on the default four-body crowd, the other models' view sweeps,
# crowd sizes, and the best-quality part cards at 20 to 1,000 humans.
set_s17() {
  local q="--impostor-parts --texels-per-pixel 2 --card-depth pass"
  flow main $C4 --frames 120
  flow main_stages $C4 --frames 60 --gpu-stages
  flow worst $C4 --frames 60 --posture 0 --view 0
  flow sweep_view $C4 --frames 60 --sweep view
  flow scaling $C4 --frames 2 --gpu-stages --scaling --scaling-humans 20,100,500,1000,2000,5000,10000 --scaling-frames 8
  flow best_8 $C4 --frames 60 --view 8 $q
  for n in 200 1000; do
    flow best_8_h$n $C4 --frames 30 --humans $n --view 8 $q --gpu-stages
    flow main_h$n $C4 --frames 30 --humans $n --gpu-stages
  done
  flow parts_view $C4 --frames 40 --sweep view --impostor-parts
  for m in CesiumMan.glb Fox.glb RiggedSimple.gltf SimpleSkin.gltf; do
    flow view_${m%%.*} --model $M/$m --frames 40 --sweep view
  done
  flow sweep_posture $C4 --frames 60 --sweep posture
  flow scaling_dw $C4 --frames 2 --distance-weighting --scaling --scaling-humans 1000,10000 --scaling-frames 8
}
# Nineteenth session (no GPU then): the worst case and the view targets at one sample (one tap per
# pixel, --impostor-taps auto) and at four, four taps against one, and the coverage fit's rule
# (boxes for short-lived snapshots) against boxes everywhere.
set_s19() {
  for a in "--msaa 1" "--msaa 4"; do
    local k=${a// /}; k=${k#--}
    flow worst_$k $C4 --frames 60 --posture 0 --view 0 $a
    flow worst_${k}_taps4 $C4 --frames 60 --posture 0 --view 0 $a --impostor-taps 4
    flow worst_${k}_taps1 $C4 --frames 60 --posture 0 --view 0 $a --impostor-taps 1
    flow worst_${k}_boxes $C4 --frames 60 --posture 0 --view 0 $a --quad-fit boxes
    flow sweep_view_$k $C4 --frames 40 --sweep view $a
  done
  flow parts_8_taps1 $C4 --frames 60 --view 8 --posture off --impostor-parts --impostor-taps 1
  flow parts_8 $C4 --frames 60 --view 8 --posture off --impostor-parts
  # The 20-human frame's fixed costs: per model (one body against four), the coverage pass (boxes),
  # and the stages' GPU times.
  flow main_1 --model $M/default.glb --frames 120
  flow main_c4 $C4 --frames 120
  flow main_c4_boxes $C4 --frames 120 --quad-fit boxes
  flow main_c4_stages $C4 --frames 60 --gpu-stages
}
# Where the impostor frame's CPU time goes at 10,000 humans and its GPU time at 20: planner threads,
# one model against four, blending's sort (the alpha test needs none), the coverage pass (boxes).
set_diag() {
  local sc="--frames 2 --scaling --scaling-humans 10000 --scaling-frames 16"
  flow d_c4_t0 $C4 $sc
  flow d_c4_t1 $C4 $sc --planner-threads 1
  flow d_c4_t4 $C4 $sc --planner-threads 4
  flow d_1_t0 --model $M/default.glb $sc
  flow d_1_t1 --model $M/default.glb $sc --planner-threads 1
  flow d_c4_test $C4 $sc --impostor-edges test
  flow d_main_1 --model $M/default.glb --frames 120
  flow d_main_boxes $C4 --frames 120 --quad-fit boxes
  flow d_worst_1 --model $M/default.glb --frames 60 --posture 0 --view 0
  flow d_worst_boxes $C4 --frames 60 --posture 0 --view 0 --quad-fit boxes
  flow d_worst_1_stages --model $M/default.glb --frames 60 --posture 0 --view 0 --gpu-stages
}
# The crowd sizes of the default crowd, with and without the paper's distance weighting.
set_crowd() {
  flow scaling $C4 --frames 2 --gpu-stages --scaling --scaling-humans 20,100,500,1000,2000,5000,10000 --scaling-frames 16
  flow scaling_dw $C4 --frames 2 --distance-weighting --scaling --scaling-humans 1000,10000 --scaling-frames 16
  flow scaling_1 --model $M/default.glb --frames 2 --scaling --scaling-humans 1000,10000 --scaling-frames 16
}
# Anyone's models in large crowds.
set_models() {
  local sc="--frames 2 --scaling --scaling-humans 1000,10000 --scaling-frames 16"
  for m in CesiumMan.glb Fox.glb RiggedSimple.gltf; do
    flow sc_${m%%.*} --model $M/$m $sc
    flow sc_${m%%.*}_dw --model $M/$m $sc --distance-weighting
  done
}
# The paper's first item of future work on a GPU: a quasi-constant frame rate from a refresh budget.
# 10,000 humans of the default crowd, no screen weighting (about 800 refreshes a frame unbudgeted).
set_budget() {
  local b="--humans 10000 --frames 60 --screen-weighting off"
  flow budget_none $C4 $b
  for n in 400 200 100; do flow budget_$n $C4 $b --refresh-budget $n; done
}
# Thirty-fourth session: the present code (windows of 16 and 8 pixels, and everything since the
# seventeenth) against the issue's targets, the paper's four window sizes against the default's, and
# anyone's models at 10,000, in order of importance (a run that would pass the time limit is skipped).
set_s34() {
  local q="--impostor-parts --texels-per-pixel 2 --impostor-edges blend --card-depth pass"
  local sc="--frames 2 --scaling --scaling-frames 16"
  flow main $C4 --frames 120
  flow worst $C4 --frames 60 --posture 0 --view 0
  flow sweep_view $C4 --frames 60 --sweep view
  flow scaling $C4 --frames 2 --gpu-stages --scaling --scaling-humans 20,100,1000,2000,5000,10000 --scaling-frames 8
  flow win_paper $C4 $sc --scaling-humans 10000 --window-sizes 256,128,64,32
  flow win_default $C4 $sc --scaling-humans 10000
  flow best_8 $C4 --frames 60 --view 8 --posture off $q
  flow parts_8 $C4 --frames 60 --view 8 --posture off --impostor-parts
  for m in RiggedSimple.gltf CesiumMan.glb Fox.glb; do flow sc_${m%%.*} --model $M/$m $sc --scaling-humans 1000,10000; done
  flow rs_orbit --model $M/RiggedSimple.gltf --frames 40 --orbit 30 --sweep view
  for n in 1000 10000; do flow best_8_h$n $C4 --frames 20 --humans $n --view 8 --posture off $q --gpu-stages; done
  flow sweep_posture $C4 --frames 60 --sweep posture
  flow demo_main $C4 --frames 60
}
# The same session's follow-ups on the warm machine: the window sizes at 10,000 alternated, crowd
# sizes where a GPU is geometry-bound (1,000 and 5,000 humans: the view sweep, the worst case, the
# posture sweep), and where the worst case's time goes.
set_s34b() {
  local sc="--frames 2 --scaling --scaling-frames 16 --gpu-stages"
  for i in 1 2 3; do
    flow win_paper_$i $C4 $sc --scaling-humans 10000 --window-sizes 256,128,64,32
    flow win_default_$i $C4 $sc --scaling-humans 10000
  done
  flow win_paper_dw $C4 $sc --scaling-humans 10000 --window-sizes 256,128,64,32 --distance-weighting
  flow win_default_dw $C4 $sc --scaling-humans 10000 --distance-weighting
  flow rs_paper --model $M/RiggedSimple.gltf $sc --scaling-humans 10000 --window-sizes 256,128,64,32
  flow rs_default --model $M/RiggedSimple.gltf $sc --scaling-humans 10000
}
set_s34c() {
  for n in 1000 5000; do
    flow sweep_view_h$n $C4 --frames 40 --humans $n --sweep view
    flow worst_h$n $C4 --frames 30 --humans $n --posture 0 --view 0
  done
  flow sweep_posture_h1000 $C4 --frames 40 --humans 1000 --sweep posture
  flow parts_view_h1000 $C4 --frames 30 --humans 1000 --sweep view --impostor-parts
  flow rs_orbit_h10000 --model $M/RiggedSimple.gltf --frames 30 --humans 10000 --orbit 30 --view 17 --posture off
}
set_s34d() {
  flow worst_h1000_st $C4 --frames 30 --humans 1000 --posture 0 --view 0 --gpu-stages
  flow worst_h1000_1 --model $M/default.glb --frames 30 --humans 1000 --posture 0 --view 0 --gpu-stages
  flow worst_h1000_msaa1 $C4 --frames 30 --humans 1000 --posture 0 --view 0 --gpu-stages --msaa 1
  flow worst_h1000_test $C4 --frames 30 --humans 1000 --posture 0 --view 0 --gpu-stages --impostor-edges test
  flow worst_h1000_t1 $C4 --frames 30 --humans 1000 --posture 0 --view 0 --planner-threads 1
  flow worst_h20_st $C4 --frames 60 --posture 0 --view 0 --gpu-stages
}
# After the worst case's planning went onto threads and its tight quads got cheaper: the worst
# case again, the snapshot pass per page against layered (BB_NO_LAYERED_SNAPSHOTS), and the
# targets' runs.
set_s34e() {
  for n in 20 1000 5000; do
    flow e_worst_h$n $C4 --frames 30 --humans $n --posture 0 --view 0 --gpu-stages
  done
  BB_NO_LAYERED_SNAPSHOTS=1 flow e_worst_h1000_pages $C4 --frames 30 --humans 1000 --posture 0 --view 0 --gpu-stages
  flow e_worst_h1000_t1 $C4 --frames 30 --humans 1000 --posture 0 --view 0 --planner-threads 1
  # The binary before the change (bench_flow_prev, where carried) against this one, alternated.
  if [ -x .gpu/bin/bench_flow_prev ]; then
    for i in 1 2; do
      B=.gpu/bin/bench_flow_prev flow e_prev_worst_h1000_$i $C4 --frames 30 --humans 1000 --posture 0 --view 0
      flow e_new_worst_h1000_$i $C4 --frames 30 --humans 1000 --posture 0 --view 0
    done
  fi
  flow e_sweep_view_h1000 $C4 --frames 40 --humans 1000 --sweep view
  flow e_sweep_posture_h1000 $C4 --frames 40 --humans 1000 --sweep posture
  flow e_main $C4 --frames 120
  flow e_sweep_view $C4 --frames 60 --sweep view
  flow e_scaling $C4 --frames 2 --gpu-stages --scaling --scaling-humans 20,100,1000,2000,5000,10000 --scaling-frames 8
}
# The worst case's remaining cost is the snapshot pass: characters refreshed in consecutive frames
# drawn as geometry instead (--short-lived geometry), into the impostor-only single-sampled target
# or into the scene's multisampled one (--impostor-target scene), and what the latter costs at the
# paper's thresholds.
set_s34f() {
  local g="--impostor-target scene --short-lived geometry"
  for n in 20 1000 5000; do
    flow f_worst_h$n $C4 --frames 30 --humans $n --posture 0 --view 0
    flow f_worst_scene_geo_h$n $C4 --frames 30 --humans $n --posture 0 --view 0 $g
    flow f_worst_geo_h$n $C4 --frames 30 --humans $n --posture 0 --view 0 --short-lived geometry
  done
  flow f_sweep_view_scene_geo $C4 --frames 40 --sweep view $g
  flow f_sweep_view_scene $C4 --frames 40 --sweep view --impostor-target scene
  flow f_sweep_view_h1000_scene_geo $C4 --frames 30 --humans 1000 --sweep view $g
  flow f_scaling_scene_geo $C4 --frames 2 --scaling --scaling-humans 1000,10000 --scaling-frames 8 $g
  flow f_scaling $C4 --frames 2 --scaling --scaling-humans 1000,10000 --scaling-frames 8
}
# flow's auto settings on a GPU after that change (impostor target of the scene's samples,
# short-lived snapshots as geometry): the worst case and the targets' runs with no flag.
set_s34g() {
  for n in 20 1000 5000; do flow g_worst_h$n $C4 --frames 30 --humans $n --posture 0 --view 0; done
  flow g_main $C4 --frames 120
  flow g_sweep_view $C4 --frames 60 --sweep view
  flow g_sweep_view_h1000 $C4 --frames 40 --humans 1000 --sweep view
  flow g_scaling $C4 --frames 2 --gpu-stages --scaling --scaling-humans 20,100,1000,2000,5000,10000 --scaling-frames 8
  flow g_best_8 $C4 --frames 60 --view 8 --posture off --impostor-parts --texels-per-pixel 2 --impostor-edges blend --card-depth pass
  flow g_sc_RiggedSimple --model $M/RiggedSimple.gltf --frames 2 --scaling --scaling-frames 16 --scaling-humans 1000,10000
}
# What the scene's samples cost the impostor frame on a GPU: auto against --impostor-target single
# (the default before), alternated.
set_s34h() {
  local sc="--frames 2 --scaling --scaling-frames 16 --gpu-stages"
  for i in 1 2 3; do
    flow h_auto_$i $C4 $sc --scaling-humans 10000
    flow h_single_$i $C4 $sc --scaling-humans 10000 --impostor-target single
  done
  for i in 1 2; do
    flow h_rs_auto_$i --model $M/RiggedSimple.gltf $sc --scaling-humans 10000
    flow h_rs_single_$i --model $M/RiggedSimple.gltf $sc --scaling-humans 10000 --impostor-target single
    flow h_view_auto_$i $C4 --frames 40 --humans 1000 --sweep view
    flow h_view_single_$i $C4 --frames 40 --humans 1000 --sweep view --impostor-target single
  done
}
# The adaptive impostor target (auto on a GPU): the worst case, and the paper's thresholds against
# --impostor-target single.
set_s34i() {
  for n in 20 1000 5000; do flow i_worst_h$n $C4 --frames 30 --humans $n --posture 0 --view 0; done
  for i in 1 2; do
    flow i_view_auto_$i $C4 --frames 40 --humans 1000 --sweep view
    flow i_view_single_$i $C4 --frames 40 --humans 1000 --sweep view --impostor-target single
  done
  flow i_main $C4 --frames 120
  flow i_scaling $C4 --frames 2 --scaling --scaling-humans 1000,10000 --scaling-frames 16
}
# The coverage pass's work groups (thirty-fifth session; not yet measured on a GPU): 16x16 (auto on
# a GPU) against 4x4 (llvmpipe's), alternated, with the stages timed: the paper's 20 humans, where
# the H200 gave the pass 0.07 ms for a snapshot or two, part cards at 8 degrees (~50 new snapshots
# a frame) and the 1,000-human worst case.
set_s35() {
  for i in 1 2 3; do
    for g in 16 4; do
      flow s35_main_g${g}_$i $C4 --frames 120 --gpu-stages --coverage-group $g
      flow s35_parts_g${g}_$i $C4 --frames 60 --gpu-stages --impostor-parts --posture off --view 8 --coverage-group $g
    done
  done
  for g in 16 4; do flow s35_worst_h1000_g$g $C4 --frames 30 --humans 1000 --posture 0 --view 0 --gpu-stages --coverage-group $g; done
  flow s35_main_boxes $C4 --frames 120 --gpu-stages --quad-fit boxes  # no coverage pass at all
  flow s35_sweep_view $C4 --frames 60 --sweep view
}
# Thirty-sixth session: refreshes ahead (--refresh-ahead) on a GPU, where a snapshot pass's fixed
# costs (0.08 ms snapshots, 0.07 ms coverage for one or two snapshots at 20 humans on the H200) are
# most of the impostor frame: alternated with off, the paper's 20 humans and 1,000.
set_s36() {
  for i in 1 2 3; do
    for a in off 0.8; do
      flow s36_main_a${a}_$i $C4 --frames 120 --gpu-stages --refresh-ahead $a
      flow s36_v8_a${a}_$i $C4 --frames 120 --posture off --view 8 --refresh-ahead $a
      flow s36_h1000_a${a}_$i $C4 --frames 40 --humans 1000 --refresh-ahead $a
    done
  done
  for a in off 0.8; do flow s36_sweep_view_a$a $C4 --frames 60 --sweep view --refresh-ahead $a; done
}
# Thirty-eighth session: quads fitted on the CPU from the skinned vertices (--quad-fit vertices: no
# coverage dispatch or barrier; the same frames, whole impostors the same times within the noise and
# part cards 4 % faster on llvmpipe) against the coverage pass, alternated: the paper's 20 humans
# (stages timed, then not), 8 degrees with the posture test off, 1,000 humans, part cards at 8.
set_s38() {
  for i in 1 2 3; do
    for q in coverage vertices; do
      flow s38_main_${q}_$i $C4 --frames 120 --quad-fit $q
      flow s38_main_stages_${q}_$i $C4 --frames 120 --gpu-stages --quad-fit $q
      flow s38_v8_${q}_$i $C4 --frames 120 --posture off --view 8 --quad-fit $q
      flow s38_h1000_${q}_$i $C4 --frames 40 --humans 1000 --quad-fit $q
      flow s38_parts_${q}_$i $C4 --frames 60 --impostor-parts --posture off --view 8 --quad-fit $q
    done
  done
}
# Thirty-ninth session: the present code against the issue's targets (the paper's 20 humans, the
# worst case, the view sweep at 20 and 1,000 humans, crowd sizes, part cards at 8 degrees, anyone's
# RiggedSimple at 10,000 and orbiting), then the vertex fit and refreshes ahead alternated with the
# defaults, twice each.
set_s39() {
  local q="--impostor-parts --texels-per-pixel 2 --impostor-edges blend --card-depth pass"
  flow s39_main $C4 --frames 120
  flow s39_worst $C4 --frames 60 --posture 0 --view 0
  flow s39_sweep_view $C4 --frames 60 --sweep view
  flow s39_scaling $C4 --frames 2 --gpu-stages --scaling --scaling-humans 20,100,1000,2000,5000,10000 --scaling-frames 8
  flow s39_sweep_view_h1000 $C4 --frames 40 --humans 1000 --sweep view
  flow s39_parts_8 $C4 --frames 60 --view 8 --posture off --impostor-parts
  flow s39_best_8 $C4 --frames 60 --view 8 --posture off $q
  flow s39_rs --model $M/RiggedSimple.gltf --frames 2 --scaling --scaling-humans 1000,10000 --scaling-frames 16
  flow s39_rs_orbit --model $M/RiggedSimple.gltf --frames 60 --orbit 30 --posture off --view 17
  flow s39_worst_h1000 $C4 --frames 30 --humans 1000 --posture 0 --view 0
}
set_s39b() {
  for i in 1 2; do
    for q in coverage vertices; do
      flow s39_main_${q}_$i $C4 --frames 120 --quad-fit $q
      flow s39_main_stages_${q}_$i $C4 --frames 120 --gpu-stages --quad-fit $q
      flow s39_parts_${q}_$i $C4 --frames 60 --impostor-parts --posture off --view 8 --quad-fit $q
    done
    for a in off 0.8; do
      flow s39_main_a${a}_$i $C4 --frames 120 --refresh-ahead $a
      flow s39_h1000_a${a}_$i $C4 --frames 40 --humans 1000 --refresh-ahead $a
    done
  done
}
# The same session: draw_many's quads put in their layers in one pass (instead of a pass a layer)
# against the binary before (bench_flow_prev), each model's quads drawn apart (BB_SEPARATE_DRAWS, a
# temporary switch in cli/flow_bed.cpp, since removed), and glibc's malloc on transparent huge pages (GLIBC_TUNABLES), alternated.
set_s39c() {
  local sc="--frames 2 --scaling --scaling-humans 1000,10000 --scaling-frames 16"
  for i in 1 2 3; do
    B=.gpu/bin/bench_flow_prev flow c_prev_sc_$i $C4 $sc
    flow c_new_sc_$i $C4 $sc
    BB_SEPARATE_DRAWS=1 flow c_sep_sc_$i $C4 $sc
    GLIBC_TUNABLES=glibc.malloc.hugetlb=1 flow c_huge_sc_$i $C4 $sc
    B=.gpu/bin/bench_flow_prev flow c_prev_h1000_$i $C4 --frames 40 --humans 1000
    flow c_new_h1000_$i $C4 --frames 40 --humans 1000
    BB_SEPARATE_DRAWS=1 flow c_sep_h1000_$i $C4 --frames 40 --humans 1000
    flow c_rs_$i --model $M/RiggedSimple.gltf $sc
    GLIBC_TUNABLES=glibc.malloc.hugetlb=1 flow c_rs_huge_$i --model $M/RiggedSimple.gltf $sc
  done
}
# One atlas for the four bodies (--atlas shared, the default since: one back-to-front draw of every
# model's quads) against an atlas each (--atlas per-model: a draw per model and per layer of
# overlaps) and against drawing model after model (BB_SEPARATE_DRAWS, a temporary switch in
# cli/flow_bed.cpp, since removed),
# alternated.
set_s39d() {
  local sc="--frames 2 --scaling --scaling-humans 1000,10000 --scaling-frames 16"
  for i in 1 2 3; do
    for a in shared per-model; do
      flow d_${a}_main_$i $C4 --frames 120 --atlas $a
      flow d_${a}_h1000_$i $C4 --frames 40 --humans 1000 --atlas $a
      flow d_${a}_sc_$i $C4 $sc --atlas $a
      flow d_${a}_parts_$i $C4 --frames 60 --impostor-parts --posture off --view 8 --atlas $a
    done
    BB_SEPARATE_DRAWS=1 flow d_sep_h1000_$i $C4 --frames 40 --humans 1000 --atlas per-model
  done
  for a in shared per-model; do flow d_${a}_sweep_view_h1000 $C4 --frames 40 --humans 1000 --sweep view --atlas $a; done
  flow d_shared_sweep_view $C4 --frames 60 --sweep view
  flow d_shared_worst_h1000 $C4 --frames 30 --humans 1000 --posture 0 --view 0
}
# The present code (one atlas for the four bodies) against the targets: set_s39's runs again, and
# the crowd sizes three times.
set_s39e() {
  local q="--impostor-parts --texels-per-pixel 2 --impostor-edges blend --card-depth pass"
  flow e39_main $C4 --frames 120
  flow e39_worst $C4 --frames 60 --posture 0 --view 0
  flow e39_sweep_view $C4 --frames 60 --sweep view
  for i in 1 2 3; do
    flow e39_scaling_$i $C4 --frames 2 --gpu-stages --scaling --scaling-humans 20,100,1000,2000,5000,10000 --scaling-frames 8
  done
  flow e39_sweep_view_h1000 $C4 --frames 40 --humans 1000 --sweep view
  flow e39_sweep_posture_h1000 $C4 --frames 40 --humans 1000 --sweep posture
  flow e39_parts_8 $C4 --frames 60 --view 8 --posture off --impostor-parts
  flow e39_best_8 $C4 --frames 60 --view 8 --posture off $q
  flow e39_worst_h1000 $C4 --frames 30 --humans 1000 --posture 0 --view 0
  flow e39_worst_h5000 $C4 --frames 20 --humans 5000 --posture 0 --view 0
  flow e39_cesium --model $M/CesiumMan.glb --frames 2 --scaling --scaling-humans 1000,10000 --scaling-frames 16
  flow e39_fox --model $M/Fox.glb --frames 2 --scaling --scaling-humans 1000,10000 --scaling-frames 16
}
# Part cards in crowds with one atlas (16 cards a human in one draw instead of layers of draws per
# model): 1,000 humans shared against per-model, crowd sizes, the best quality at 1,000.
set_s39f() {
  for i in 1 2; do
    for a in shared per-model; do
      flow f39_parts_h1000_${a}_$i $C4 --frames 30 --humans 1000 --impostor-parts --atlas $a
    done
  done
  flow f39_parts_scaling $C4 --frames 2 --impostor-parts --scaling --scaling-humans 1000,5000,10000 --scaling-frames 8
  flow f39_parts_view_h1000 $C4 --frames 30 --humans 1000 --impostor-parts --sweep view
  flow f39_best_h1000 $C4 --frames 30 --humans 1000 --view 8 --posture off --impostor-parts --texels-per-pixel 2 --impostor-edges blend --card-depth pass
}
# Whole impostors on the pixel grid, 1/8 pixel off, with one tap (--snapshot-grid auto, the default
# since the fortieth session) against two taps on the free grid (--snapshot-grid free), alternated:
# measured on llvmpipe only so far.
set_s40() {
  for i in 1 2 3; do
    for g in auto free; do
      flow g40_${g}_main_$i $C4 --frames 120 --snapshot-grid $g
      flow g40_${g}_worst_$i $C4 --frames 60 --posture 0 --view 0 --snapshot-grid $g
      flow g40_${g}_h1000_$i $C4 --frames 40 --humans 1000 --snapshot-grid $g
      flow g40_${g}_rs_orbit_$i --model $M/RiggedSimple.gltf --frames 90 --orbit 30 --posture off --view 17 --snapshot-grid $g
    done
  done
  for g in auto free; do flow g40_${g}_sweep_view_h1000 $C4 --frames 40 --humans 1000 --sweep view --snapshot-grid $g; done
}
# Forty-first session (no GPU then): the targets under settings the issue does not name, as
# bench/flow/targets_matrix.sh runs them on llvmpipe (docs/results.md), with the default crowd built
# beforehand and the external models.
set_s41() {
  for x in "--size 640x480" "--size 1920x1080" "--humans 50" "--humans 200" "--msaa 8" "--orbit -20 --humans 40" \
           "--orbit 90" "--msaa 1"; do
    # shellcheck disable=SC2086  # a setting is a list of flags
    flow "t41_crowd_$(echo $x | tr -c 'a-z0-9' '_')" $C4 --frames 30 --targets $x
  done
  flow t41_cesium_fox --model $M/CesiumMan.glb --model $M/Fox.glb --size 800x600 --frames 30 --targets
  flow t41_fox_orbit45 --model $M/Fox.glb --humans 60 --orbit 45 --frames 30 --targets
  flow t41_rs_orbit30 --model $M/RiggedSimple.gltf --size 640x480 --orbit 30 --frames 30 --targets
  flow t41_parts_cesium --model $M/CesiumMan.glb --impostor-parts --frames 30 --targets
  flow t41_cesium_10k --model $M/CesiumMan.glb --size 1600x900 --frames 30 --targets --scaling --scaling-humans 10000 --scaling-frames 3
}
# Forty-second session (no GPU then): leading whole impostors (--view-lead) against none,
# alternated, where the view is the error (poses held) and with a fast-turning camera around cheap
# models, where a GPU pays a snapshot pass's fixed costs more than llvmpipe does.
set_s42() {
  for i in 1 2; do
    for l in off 0.5; do
      flow l42_${l}_held_$i $C4 --frames 60 --posture off --view 8 --hold-poses --view-lead $l
      flow l42_${l}_main_h1000_$i $C4 --frames 40 --humans 1000 --view-lead $l
      flow l42_${l}_fox_orbit90_$i --model $M/Fox.glb --frames 60 --orbit 90 --posture off --view 17 --view-lead $l
    done
  done
}
# Fifty-second session: the present code (back faces culled, triangles in vertex cache order, taps
# kept on their own quad, everything since the thirty-ninth) against the targets, in order of importance.
set_s52() {
  local q="--impostor-parts --texels-per-pixel 2 --impostor-edges blend --card-depth pass"
  flow e52_main $C4 --frames 120
  flow e52_worst $C4 --frames 60 --posture 0 --view 0
  flow e52_sweep_view $C4 --frames 60 --sweep view
  flow e52_scaling_1 $C4 --frames 2 --gpu-stages --scaling --scaling-humans 20,100,1000,2000,5000,10000 --scaling-frames 8
  flow e52_sweep_view_h1000 $C4 --frames 40 --humans 1000 --sweep view
  flow e52_rs --model $M/RiggedSimple.gltf --frames 2 --scaling --scaling-humans 1000,10000 --scaling-frames 16
  flow e52_parts_8 $C4 --frames 60 --view 8 --posture off --impostor-parts
  flow e52_best_8 $C4 --frames 60 --view 8 --posture off $q
  flow e52_cesium --model $M/CesiumMan.glb --frames 2 --scaling --scaling-humans 1000,10000 --scaling-frames 16
  flow e52_fox --model $M/Fox.glb --frames 2 --scaling --scaling-humans 1000,10000 --scaling-frames 16
  flow e52_worst_h1000 $C4 --frames 30 --humans 1000 --posture 0 --view 0
  flow e52_scaling_2 $C4 --frames 2 --gpu-stages --scaling --scaling-humans 20,100,1000,2000,5000,10000 --scaling-frames 8
  flow e52_sweep_posture_h1000 $C4 --frames 40 --humans 1000 --sweep posture
}
# The same session: the thirty-ninth session's binary (.gpu/bin/bench_flow_prev, built from 7059f01)
# against the present one, and the present one on the free grid (the thirty-ninth's) against auto
# (the pixel grid), alternated: where the impostor frame's time went since then.
flowp() { local B=.gpu/bin/bench_flow_prev; flow "$@"; }
set_s52b() {
  for i in 1 2; do
    flowp p52_prev_h1000_v8_$i $C4 --frames 40 --humans 1000 --posture off --view 8 --gpu-stages
    flow p52_new_h1000_v8_$i $C4 --frames 40 --humans 1000 --posture off --view 8 --gpu-stages
    flow p52_free_h1000_v8_$i $C4 --frames 40 --humans 1000 --posture off --view 8 --gpu-stages --snapshot-grid free
    flowp p52_prev_10k_$i $C4 --frames 2 --gpu-stages --scaling --scaling-humans 10000 --scaling-frames 8
    flow p52_new_10k_$i $C4 --frames 2 --gpu-stages --scaling --scaling-humans 10000 --scaling-frames 8
    flow p52_free_10k_$i $C4 --frames 2 --gpu-stages --scaling --scaling-humans 10000 --scaling-frames 8 --snapshot-grid free
    flowp p52_prev_main_$i $C4 --frames 60 --gpu-stages
    flow p52_new_main_$i $C4 --frames 60 --gpu-stages
    flow p52_free_main_$i $C4 --frames 60 --gpu-stages --snapshot-grid free
  done
}
# The same session, after --snapshot-grid auto went to the free grid on a GPU: auto against the pixel
# grid, alternated three times; the 1,000-human view sweep in both orders with the GPU's stages timed
# (does geometry's time follow the threshold or the time into the run?); then s52's runs again.
set_s52c() {
  for i in 1 2 3; do
    flow c52_auto_main_$i $C4 --frames 60
    flow c52_pixels_main_$i $C4 --frames 60 --snapshot-grid pixels
    flow c52_auto_h1000_v8_$i $C4 --frames 40 --humans 1000 --posture off --view 8
    flow c52_pixels_h1000_v8_$i $C4 --frames 40 --humans 1000 --posture off --view 8 --snapshot-grid pixels
  done
  flow c52_sweep_up_h1000 $C4 --frames 40 --humans 1000 --sweep view --sweep-thresholds 0,5,8,17,30 --gpu-stages
  flow c52_sweep_down_h1000 $C4 --frames 40 --humans 1000 --sweep view --sweep-thresholds 30,17,8,5,0 --gpu-stages
  set_s52
}
# The same session: the planner's threads on a 16-thread host. Characters a planning thread
# (FramePlanner::kCharactersPerThread, 512, through a temporary switch BB_TMP_PER_THREAD, since
# removed) against 128 and 32, alternated three times, with small crowds chunked where the models'
# joint work is enough (plan_many).
set_s52d() {
  for i in 1 2 3; do
    for per in 512 128 32; do
      BB_TMP_PER_THREAD=$per flow d52_${per}_h1000_v8_$i $C4 --frames 40 --humans 1000 --posture off --view 8
      BB_TMP_PER_THREAD=$per flow d52_${per}_h2000_$i $C4 --frames 30 --humans 2000
    done
  done
  for i in 1 2; do
    for per in 512 128; do
      BB_TMP_PER_THREAD=$per flow d52_${per}_10k_$i $C4 --frames 2 --scaling --scaling-humans 10000 --scaling-frames 8
    done
  done
}
# The same session's code at its end (the free grid on a GPU, a planning thread per 32 characters):
# 1,000 and 2,000 humans three times, then s52's runs.
set_s52e() {
  for i in 1 2 3; do
    flow f52_h1000_v8_$i $C4 --frames 40 --humans 1000 --posture off --view 8
    flow f52_h1000_$i $C4 --frames 40 --humans 1000
    flow f52_h2000_$i $C4 --frames 30 --humans 2000
  done
  set_s52
}
# Fifty-third session (no GPU lent then): quads pulled by the vertex shader (--quad-fetch pulled, the
# default on llvmpipe) against instanced strips (a GPU's default), alternated in short runs (the
# geometry pass's time drifts up in long ones): 10,000 humans of the four bodies and of RiggedSimple,
# 1,000 at 8 degrees, and part cards at 8 degrees.
set_s53() {
  for i in 1 2 3; do
    for q in instanced pulled; do
      flow q53_${q}_10k_$i $C4 --frames 2 --scaling --scaling-humans 10000 --scaling-frames 8 --quad-fetch $q
      flow q53_${q}_rs10k_$i --model $M/RiggedSimple.gltf --frames 2 --scaling --scaling-humans 10000 --scaling-frames 8 --quad-fetch $q
      flow q53_${q}_h1000_v8_$i $C4 --frames 30 --humans 1000 --posture off --view 8 --quad-fetch $q
      flow q53_${q}_parts_v8_$i $C4 --frames 30 --impostor-parts --posture off --view 8 --quad-fetch $q
    done
  done
}
# Fifty-fourth session (no GPU lent then): the quads written straight into the mapped buffer and
# draw_many's keys written in place (CPU work before the quads' draw at 10,000 humans on the 2-core
# machine: 0.77-0.88 -> 0.39-0.49 ms), the binary before (PREV=ead7d1b bash bench/flow/gpu_prepare.sh)
# against this one, alternated in short runs: 10,000 and 1,000 humans of the four bodies.
set_s54() {
  for i in 1 2 3; do
    flowp p54_prev_10k_$i $C4 --frames 2 --scaling --scaling-humans 10000 --scaling-frames 8
    flow p54_now_10k_$i $C4 --frames 2 --scaling --scaling-humans 10000 --scaling-frames 8
    flowp p54_prev_h1000_$i $C4 --frames 30 --humans 1000
    flow p54_now_h1000_$i $C4 --frames 30 --humans 1000
  done
}
for set in ${@:-main}; do set_$set; done
(cd "$R" && tar czf "$OUT/gpu_results.tar.gz" --exclude='frame_*.png' . ; ls main/*.png 2>/dev/null | head -2 | xargs -r -I{} cp {} "$OUT/")
ls -la "$OUT"
