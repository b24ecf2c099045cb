#!/usr/bin/env bash
# The GPU-speed measurements of issue 13 in one device call: the paper's Table 1 (plain
# estimator) and the equal-spp comparison with Mitsuba 3 (raylume with NEE + MIS + Russian roulette
# from segment T1_RR, default 4: Mitsuba's `path` at its rr_depth 5), every schedule x BVH layout x reorder, and the living room
# from file to a 10-spp PNG (raylume's `render`, Mitsuba's load + first render). See
# tools/table1/README.md.
#
#   tools/table1/table1.sh stage                         # here: build, strip, fill .gpu/
#   . .gl/on-device.sh && bash .gpu/table1-device.sh     # there (the device tool's run)
#
# Settings (environment): T1_SCENES (Table 1's scenes), T1_SPP (1,10,100), T1_SCHEDULES
# (megakernel,wavefront,persistent), T1_BVH (binary,wide), T1_REORDER (off,on), T1_WALK (off,on:
# the wavefront's walk stage, bench --walk-stage; it changes nothing of the other schedules,
# whose `+walk` columns repeat them), T1_QUICK=1 (the
# Cornell box and the living room only), T1_PERSISTENT_THREADS (the persistent schedule's thread
# counts tried besides the default, RAYLUME_PERSISTENT_THREADS), T1_PARTS (which parts run: "plain
# nee threads mitsuba first-image large specialise", all by default; `specialise` is issue 14's:
# every scene with its pipelines composed, overridden and generic, then with each absent feature
# compiled in (present but unused; T1_SPECIALISE_EXTRA=0 skips that); `cpu-specialise` the same
# on the host's CPU (the mirror's variant against its generic code, T1_CPU_SIZE, default
# 600x600, 4 spp, both estimators); `feature-cost` times the Cornell box and its one-feature
# variants (tools/features/cornell_variants.py) on the GPU and the CPU; `parts` is issue 16's: a render whole and as 4 parts in
# separate processes (the overhead of splitting), merged, and --backend gpus on the one GPU;
# `two-gpus` (not in the default set) is issue 17's: the living room and the Cornell box at
# 1000 spp on one GPU and split over all (`--backend gpus`), best of 3, images held to the
# merge bound (T1_GPUS_SIZE, T1_GPUS_SPP, T1_GPUS_ROUNDS shrink it for a dry run);
# `workgroup` times the Cornell box and the living room with RAYLUME_WORKGROUP_SIZE in
# T1_WORKGROUPS (default "32 64 128 256"); `stage-knobs` (not in the default set) times the
# wavefront with its walk stage (and, with NEE, shadow stage) under each of the stages' run-time
# knobs (workgroup size, refill threshold, stage workgroups, first bounce); `ab` alternates
# .gpu/bench-base.xz (another commit's bench) with this commit's (T1_AB_*); `batch` times
# batches of T1_BATCH_SPP samples per pixel; `stages` (not in the default set) gives the living
# room's seconds per GPU pass with its own BSDFs and with every BSDF one kind, and times the
# shadow stage against propagate's own shadow walks (docs/study/h200-ce89268-stages.md;
# T1_STAGES_SIZE and T1_STAGES_SPP, default 1000x1000 and 100, shrink it for a dry run);
# `large` is issue 19's: the 3M-triangle
# grid of tools/large made there and rendered from file to a 10-spp PNG by raylume and by
# Mitsuba, T1_GRID quads a side, default 1224, T1_ROUNDS rounds of a process per BVH builder in
# T1_BUILDERS (default "auto") and Mitsuba's; `builders` renders the living room at 10 and 100 spp
# per builder; `crossing` times the persistent schedule against the wavefront with its stages
# at T1_CROSSING_SPP on the large scenes, where Tracer::schedule's default switches; `race` the
# living room from file to a 10-spp PNG with the default schedule, with persistent and by
# Mitsuba, cold and warm, T1_RACE_ROUNDS rounds). Results: $OUT/table1.tgz.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
mode=${1:-}

stage() {
  local root; root=$(git -C "$here" rev-parse --show-toplevel)
  cd "$root"
  [ -d .gl ] || ../shared/gpu/prepare.sh
  mkdir -p .gpu
  # T1_STAGE_BINS: the binaries to stage (all by default); the parts' needs are in the check
  # at the end. A binary left out is removed from .gpu, so a stale one is not carried.
  local bins=${T1_STAGE_BINS:-bench render make_grid merge compare shader_stats} b
  for b in bench render make_grid merge compare shader_stats; do rm -f .gpu/$b.xz; done
  cargo build --release -p raylume $(for b in $bins; do printf -- '--example %s ' "$b"; done)
  for b in $bins; do
    cp target/release/examples/$b .gpu/$b && strip .gpu/$b && xz -f -T2 .gpu/$b
  done
  [ -f .gpu/mitsuba-trim.tar.xz ] || ../shared/peers/mitsuba/pack.sh
  cp ../shared/peers/mitsuba/tungsten.py ../shared/peers/mitsuba/cornell.py .gpu/
  cp "$here/mitsuba_table1.py" "$here/../large/mitsuba_grid.py" "$here/../large/large.sh" .gpu/
  cp "$here/table1.sh" .gpu/table1-device.sh
  git rev-parse --short HEAD > .gpu/commit.txt
  git status --porcelain --untracked-files=no | grep -q . && echo "(uncommitted changes)" >> .gpu/commit.txt
  du -sh .gpu
  # The device tool carries the working tree's tracked files with .gl and .gpu: 64 MiB at most.
  local tracked carried
  # (summed by awk: xargs may split a long list over several `du -c`, each with its own total)
  tracked=$(git ls-files -z | xargs -0 stat -c %s | awk '{s += $1} END {print s}')
  carried=$(du -sb .gl .gpu | awk '{s += $1} END {print s}')
  if [ $((tracked + carried)) -gt $((64 * 1024 * 1024)) ]; then
    echo "table1 stage: $(awk -v b=$((tracked + carried)) 'BEGIN { printf "%.2f", b / 1048576 }')" \
      "MiB with the tracked files: over the device" \
      "tool's 64 MiB. Stage only what the call's parts run, e.g. T1_STAGE_BINS=\"bench render\"" \
      "(plain, nee, mitsuba, race, crossing, ab; + compare and shader_stats for stages," \
      "+ compare for two-gpus, + make_grid for large, + merge for parts), or remove" \
      ".gpu/mitsuba-trim.tar.xz" \
      "for a call without Mitsuba" >&2
  fi
}

device() {
  cd "$(dirname "$0")/.."
  local R m S rr
  # Where raylume's NEE runs begin Russian roulette: segment 4 is Mitsuba's `path` at its
  # default rr_depth 5. Mitsuba counts a path's hits from 1 and tests `depth >= rr_depth` after
  # incrementing (src/integrators/path.cpp; its docs: rr_depth 1 "may randomly cease after
  # encountering directly visible surfaces"), so its first roulette follows its 5th hit;
  # raylume counts segments from 0, the camera ray's, and rolls after each segment >= the
  # start (until session 46 these runs took 5, a segment later than Mitsuba's).
  rr=${T1_RR:-4}
  T0=$(date +%s)
  el() { echo $(($(date +%s) - T0)); }
  R=/tmp/t1; rm -rf $R; mkdir -p $R
  trap 'tar czf "$OUT/table1.tgz" -C '$R' . ; echo "== done at $(el) s"' EXIT
  for b in bench render make_grid merge compare shader_stats bench-base; do [ -f .gpu/$b.xz ] && xz -dc .gpu/$b.xz > /tmp/$b && chmod +x /tmp/$b; done
  m=$(mktemp -d); [ -f .gpu/mitsuba-trim.tar.xz ] && tar -C "$m" -xJf .gpu/mitsuba-trim.tar.xz
  export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}
  cp .gpu/commit.txt $R/
  nvidia-smi --query-gpu=name,driver_version,clocks.max.sm,memory.total --format=csv | tee $R/gpu.txt
  S=${T1_SCENES:-"scenes/cornell-box.toml scenes/living-room/scene.json scenes/teapot.toml scenes/glass-teapot.toml scenes/spheres.toml scenes/cornell-plus.toml"}
  [ "${T1_QUICK:-0}" = 1 ] && S="scenes/cornell-box.toml scenes/living-room/scene.json"
  local common="--backend gpu --spp ${T1_SPP:-1,10,100} --repeat 3 --schedule ${T1_SCHEDULES:-megakernel,wavefront,persistent} --reorder ${T1_REORDER:-off,on} --bvh ${T1_BVH:-binary,wide} --walk-stage ${T1_WALK:-off,on}"
  local parts=" ${T1_PARTS:-plain nee threads mitsuba first-image large specialise parts workgroup} "
  if [[ $parts == *" plain "* ]]; then
  echo "== Table 1, plain estimator (at $(el) s)"
  timeout 300 /tmp/bench $common --json $R/plain.json $S > $R/plain.md 2> $R/plain.log || echo "bench plain: exit $?"
  awk '/^\| scene \| prims \| spp/{p=1} /^$/{p=0} p' $R/plain.md
  fi
  if [[ $parts == *" nee "* ]]; then
  echo "== NEE + MIS + roulette from $rr, independent sampler (at $(el) s)"
  timeout 200 /tmp/bench $common --estimator nee --rr-depth $rr --json $R/nee.json \
    scenes/cornell-box.toml scenes/living-room/scene.json > $R/nee.md 2> $R/nee.log || echo "bench nee: exit $?"
  awk '/^\| scene \| prims \| spp/{p=1} /^$/{p=0} p' $R/nee.md
  fi
  if [[ $parts == *" threads "* ]]; then
  echo "== the persistent schedule's thread count (NEE, wide, 100 spp; at $(el) s)"
  local th
  for th in ${T1_PERSISTENT_THREADS:-131072 262144 2097152}; do
    RAYLUME_PERSISTENT_THREADS=$th timeout 60 /tmp/bench --backend gpu --spp 100 --repeat 3 \
      --schedule persistent --reorder off --bvh wide --estimator nee --rr-depth $rr \
      --json $R/persistent-$th.json scenes/cornell-box.toml scenes/living-room/scene.json \
      > $R/persistent-$th.md 2>/dev/null || echo "bench persistent $th: exit $?"
    echo "threads $th:"; grep -E '^\| scenes.* \| 100 \| [0-9.]+ \|$' $R/persistent-$th.md || true
  done
  fi
  if [[ $parts == *" mitsuba "* ]]; then
  echo "== Mitsuba 3 (at $(el) s)"
  PYTHONPATH=$m timeout 100 python3 .gpu/cornell.py $R cuda_ad_rgb 2>&1 | tail -3 || true
  PYTHONPATH=$m timeout 200 python3 .gpu/mitsuba_table1.py scenes/living-room $R --tungsten .gpu/tungsten.py 2>&1 | tail -5 || true
  fi
  if [[ $parts == *" first-image "* ]]; then
  echo "== the living room from file to a 10-spp PNG (at $(el) s)"
  # Each layout twice: the first process compiles the pipelines, the second may find them in
  # the driver's own shader cache. Mitsuba likewise: its first process (unless the mitsuba
  # part ran above) JIT-compiles, the next one finds its kernel cache.
  local l k
  for l in $(echo "${T1_BVH:-binary,wide}" | tr , ' '); do
    for k in 1 2; do
      TIMEFORMAT="raylume $l, process $k: %R s"
      time (timeout 60 /tmp/render scenes/living-room/scene.json -o /tmp/lr-$l.png --backend gpu \
        --spp 10 --bvh $l --stats $R/render-lr-$l-$k.json -q 2>&1 | grep -E '^raylume: trace')
    done
  done
  for k in 1 2; do
    TIMEFORMAT="mitsuba, process $k: %R s"
    time (PYTHONPATH=$m timeout 100 python3 .gpu/mitsuba_table1.py scenes/living-room /tmp/mi$k \
      --tungsten .gpu/tungsten.py --spp 1 > /tmp/mi$k.log 2>&1 || true)
    head -1 /tmp/mi$k.log
    cp /tmp/mi$k/living-room-mi-table1.json $R/mitsuba-first-image-$k.json 2>/dev/null || true
  done
  fi
  if [[ $parts == *" specialise "* ]]; then
  local S6="scenes/cornell-box.toml scenes/living-room/scene.json scenes/teapot.toml scenes/glass-teapot.toml scenes/spheres.toml scenes/cornell-plus.toml"
  local one="--backend gpu --repeat 3 --schedule megakernel --reorder off --bvh wide"
  echo "== issue 14: composed, overrides, generic; plain estimator (at $(el) s)"
  timeout 200 /tmp/bench $one --spp 10,100 --specialise composed,overrides,generic \
    --json $R/specialise-plain.json $S6 > $R/specialise-plain.md 2> $R/specialise-plain.log || echo "bench: exit $?"
  awk '/^\| scene \| prims \| spp/{p=1} /^$/{p=0} p' $R/specialise-plain.md
  echo "== the same, NEE + MIS + roulette from $rr (at $(el) s)"
  timeout 150 /tmp/bench $one --spp 100 --specialise composed,overrides,generic --estimator nee --rr-depth $rr \
    --json $R/specialise-nee.json $S6 > $R/specialise-nee.md 2> $R/specialise-nee.log || echo "bench: exit $?"
  awk '/^\| scene \| prims \| spp/{p=1} /^$/{p=0} p' $R/specialise-nee.md
  if [ "${T1_SPECIALISE_EXTRA:-1}" = 1 ]; then
  echo "== each feature present but unused (composed, plain, 100 spp; at $(el) s)"
  timeout 240 /tmp/bench $one --spp 100 --specialise composed \
    --extra-feature diffuse,metal,rough_metal,glass,rough_glass,plastic,emission,spheres,textures,shading_normals,constant_environment,environment_map \
    --json $R/extra.json $S6 > $R/extra.md 2> $R/extra.log || echo "bench: exit $?"
  awk '/^\| scene \| prims \| spp/{p=1} /^$/{p=0} p' $R/extra.md
  fi
  fi
  if [[ $parts == *" feature-cost "* ]]; then
  # Issue 14's "what a feature costs when used": the Cornell box and its one-feature variants
  # (tools/features/cornell_variants.py), each with its specialised code, GPU and CPU.
  local V; V=$(python3 tools/features/cornell_variants.py scenes/cornell-box.toml /tmp/variants)
  local est opts
  for est in plain nee; do
    opts="--estimator plain"
    [ $est = nee ] && opts="--estimator nee --sampler sobol --rr-depth $rr"
    echo "== feature cost, GPU, $est (at $(el) s)"
    timeout 150 /tmp/bench --backend gpu --spp 100 --repeat 3 --schedule megakernel --reorder off \
      --bvh wide $opts --json $R/feature-cost-gpu-$est.json $V > $R/feature-cost-gpu-$est.md \
      2> $R/feature-cost-gpu-$est.log || echo "bench: exit $?"
    awk '/^\| scene \| prims \| backend/{p=1} /^$/{p=0} p' $R/feature-cost-gpu-$est.md
    echo "== feature cost, CPU ($(nproc) threads), $est (at $(el) s)"
    timeout 150 /tmp/bench --backend cpu --size ${T1_CPU_SIZE:-600x600} --spp 4 --repeat 5 \
      $opts --json $R/feature-cost-cpu-$est.json $V > $R/feature-cost-cpu-$est.md \
      2> $R/feature-cost-cpu-$est.log || echo "bench: exit $?"
    awk '/^\| scene \| prims \| backend/{p=1} /^$/{p=0} p' $R/feature-cost-cpu-$est.md
  done
  fi
  if [[ $parts == *" cpu-specialise "* ]]; then
  # Issue 14 on the host's CPU: the mirror's variant against its generic code, per estimator.
  local S6="scenes/cornell-box.toml scenes/living-room/scene.json scenes/teapot.toml scenes/glass-teapot.toml scenes/spheres.toml scenes/cornell-plus.toml"
  local est
  for est in plain nee; do
    echo "== issue 14 on the CPU ($(nproc) threads): specialised and generic, $est (at $(el) s)"
    local opts="--estimator plain"
    [ $est = nee ] && opts="--estimator nee --sampler sobol --rr-depth $rr"
    timeout 200 /tmp/bench --backend cpu --size ${T1_CPU_SIZE:-600x600} --spp 4 --repeat 5 \
      --specialise composed,generic $opts --json $R/cpu-specialise-$est.json $S6 \
      > $R/cpu-specialise-$est.md 2> $R/cpu-specialise-$est.log || echo "bench: exit $?"
    awk '/^\| scene \| prims \| spp/{p=1} /^$/{p=0} p' $R/cpu-specialise-$est.md
  done
  fi
  if [[ $parts == *" ab "* ]]; then
  # An A/B of two builds in one call: .gpu/bench-base.xz (the bench of another commit, named
  # in .gpu/base-commit.txt: copy .gpu/bench.xz and commit.txt there before staging the
  # change) against this commit's bench, alternating, T1_AB_ROUNDS rounds, each estimator of
  # T1_AB_ESTIMATORS over T1_AB_SCENES with the wavefront and its stages (T1_AB_ARGS more).
  local r est ab_scenes=${T1_AB_SCENES:-"scenes/living-room/scene.json scenes/teapot.toml"}
  echo "== A/B: base $(cat .gpu/base-commit.txt 2>/dev/null), this $(cat .gpu/commit.txt)"
  for r in $(seq ${T1_AB_ROUNDS:-3}); do
    for est in ${T1_AB_ESTIMATORS:-nee plain}; do
      for b in bench-base bench; do
        echo "== A/B round $r, $est, $b (at $(el) s)"
        timeout 120 /tmp/$b --backend gpu --spp 100 --repeat 3 --schedule wavefront --reorder off \
          --bvh wide --walk-stage on --estimator $est $([ $est = nee ] && echo --rr-depth $rr) \
          ${T1_AB_ARGS:-} --json $R/ab-$r-$est-$b.json $ab_scenes > $R/ab-$r-$est-$b.md \
          2> $R/ab-$r-$est-$b.log || echo "bench: exit $?"
        grep -E '^\| scenes.* \| 100 \| [0-9.]+ \|$' $R/ab-$r-$est-$b.md || true
      done
    done
  done
  fi
  if [[ $parts == *" batch "* ]]; then
  # The samples per pixel of a batch (the paper's 20; the adapter's binding size bounds it:
  # bench says what ran), T1_BATCH_SPP, the wavefront with its stages.
  local bs est
  for bs in ${T1_BATCH_SPP:-20 25 33}; do
    for est in nee plain; do
      echo "== batch spp $bs, $est (at $(el) s)"
      timeout 120 /tmp/bench --backend gpu --spp 100 --repeat 3 --schedule wavefront --reorder off \
        --bvh wide --walk-stage on --estimator $est $([ $est = nee ] && echo --rr-depth $rr) \
        --batch-spp $bs --json $R/batch-$bs-$est.json scenes/living-room/scene.json scenes/teapot.toml \
        > $R/batch-$bs-$est.md 2> $R/batch-$bs-$est.log || echo "bench: exit $?"
      grep -E '^\| scenes.* \| 100 \| [0-9.]+ \|$' $R/batch-$bs-$est.md || true
    done
  done
  fi
  if [[ $parts == *" stage-knobs "* ]]; then
  # The wavefront's stages (walk, and shadow with NEE) under their run-time knobs, one at a
  # time from the defaults: every kernel's workgroup size, the refill threshold and the
  # stages' workgroup count (T1_KNOB_SCENES, default the living room and the teapot).
  local kn kv est ks=${T1_KNOB_SCENES:-"scenes/living-room/scene.json scenes/teapot.toml"}
  for kn in "RAYLUME_WORKGROUP_SIZE=64" "RAYLUME_WORKGROUP_SIZE=128" "RAYLUME_WORKGROUP_SIZE=256" \
            "RAYLUME_WALK_STAGE_REFILL=4" "RAYLUME_WALK_STAGE_REFILL=16" \
            "RAYLUME_WALK_STAGE_GROUPS=2048" "RAYLUME_WALK_STAGE_GROUPS=8192" \
            "RAYLUME_WALK_STAGE_FROM=1"; do
    for est in plain nee; do
      echo "== stage knobs: $kn, $est (at $(el) s)"
      env "$kn" timeout 120 /tmp/bench --backend gpu --spp 100 --repeat 3 --schedule wavefront \
        --reorder off --bvh wide --walk-stage on --estimator $est $([ $est = nee ] && echo --rr-depth $rr) \
        --json $R/knob-$kn-$est.json $ks > $R/knob-$kn-$est.md 2> $R/knob-$kn-$est.log || echo "bench: exit $?"
      grep -E '^\| scenes.* \| 100 \|' $R/knob-$kn-$est.md || true
    done
  done
  fi
  if [[ $parts == *" workgroup "* ]]; then
  local wg est
  for wg in ${T1_WORKGROUPS:-32 64 128 256}; do
    for est in plain nee; do
      echo "== workgroup size $wg, $est (at $(el) s)"
      RAYLUME_WORKGROUP_SIZE=$wg timeout 120 /tmp/bench --backend gpu --spp 100 --repeat 3 \
        --schedule megakernel,persistent --reorder off --bvh wide --estimator $est --rr-depth $rr \
        --json $R/wg-$wg-$est.json scenes/cornell-box.toml scenes/living-room/scene.json \
        > $R/wg-$wg-$est.md 2> $R/wg-$wg-$est.log || echo "bench: exit $?"
      grep -E '^\| scenes.* \| 100 \|' $R/wg-$wg-$est.md || true
    done
  done
  fi
  if [[ $parts == *" stages "* ]]; then
  # Where the living room's wavefront time goes (docs/study/h200-ce89268-stages.md): the
  # GPU's seconds per pass (render --stats) as is, with every BSDF one kind (is propagate's
  # cost the materials' divergence?), and with NEE's shadow rays in the shadow stage; then
  # the shadow stage against propagate's own walks, two rounds.
  local lr=scenes/living-room v ss=${T1_STAGES_SIZE:-1000x1000} sp=${T1_STAGES_SPP:-100}
  python3 - "$lr" <<'PY'
import copy, json, sys
d = json.load(open(sys.argv[1] + "/scene.json"))
plastic = {"ior": 1.5, "thickness": 1.0, "sigma_a": 0.0, "distribution": "ggx", "roughness": 0.15}
for kind in ("lambert", "rough_plastic"):
    e = copy.deepcopy(d)
    e["bsdfs"] = [dict({"name": b["name"], "albedo": b.get("albedo", 0.8), "type": kind},
                       **(plastic if kind == "rough_plastic" else {})) for b in e["bsdfs"]]
    json.dump(e, open(f"{sys.argv[1]}/scene-{kind}.json", "w"))
PY
  kernels() { python3 -c "
import json, sys; d = json.load(open(sys.argv[1])); k = dict(d['kernel_seconds'])
print(sys.argv[2], 'trace %.4f' % d['seconds']['trace'], 'rays %d' % d['rays_traced'],
      ' '.join('%s %.4f' % (n, k[n]) for n in ('raygen', 'trace_hits', 'propagate', 'trace_shadows') if n in k),
      'propagate ns/ray %.3f' % (k['propagate'] / d['rays_traced'] * 1e9))" "$@"; }
  for v in scene scene-lambert scene-rough_plastic; do
    echo "== stages: $v, plain (at $(el) s)"
    /tmp/render $lr/$v.json -o /tmp/x.png --backend gpu --schedule wavefront --walk-stage on \
      --estimator plain --rr-depth off --sampler independent --bvh-preset quality --spp $sp --bounces 10 \
      --size $ss -q --no-bloom --stats $R/stages-$v.json > /dev/null 2>&1 || echo "render: exit $?"
    kernels $R/stages-$v.json "$v plain" || true
  done
  # The walk stage changes no image (tests/schedules.rs, on lavapipe): the same on the GPU?
  for v in off on; do
    /tmp/render $lr/scene.json -o /tmp/walk-$v.exr --backend gpu --schedule wavefront --walk-stage $v \
      --estimator plain --rr-depth off --sampler independent --bvh-preset quality --spp 10 --bounces 10 \
      --size $ss -q --no-bloom > /dev/null 2>&1 || echo "render: exit $?"
  done
  echo "== stages: the living room with the walk stage against without it (RMSE 0: the same image)"
  /tmp/compare /tmp/walk-on.exr /tmp/walk-off.exr 2>&1 | head -3
  for v in off on; do
    local shadow="--shadow-stage $v"
    echo "== stages: NEE + roulette 5, shadow stage $v (at $(el) s)"
    /tmp/render $lr/scene.json -o /tmp/nee-shadow-$v.exr --backend gpu --schedule wavefront --walk-stage on \
      $shadow --estimator nee --rr-depth $rr --sampler independent --environment-guide off \
      --bvh-preset quality --spp $sp --bounces 10 --size $ss -q --no-bloom \
      --stats $R/stages-nee-$v.json > /dev/null 2>&1 || echo "render: exit $?"
    kernels $R/stages-nee-$v.json "nee, shadow stage $v" || true
  done
  echo "== stages: NEE with the shadow stage against without it (RMSE 0: the same image)"
  /tmp/compare /tmp/nee-shadow-on.exr /tmp/nee-shadow-off.exr 2>&1 | head -3
  # The stages' registers and spills (trace_hits and trace_shadows share their refill since
  # 46a7a42, measured nowhere yet).
  echo "== stages: registers of the wavefront's pipelines with the walk and shadow stages"
  timeout 120 /tmp/shader_stats --walk-stage --schedule wavefront --sampler independent \
    $lr/scene.json 2>&1 | tail -20 || true
  # What the Sobol' sampler (the library's default; the rows above and Mitsuba take
  # independent numbers) costs in each pass.
  echo "== stages: NEE + roulette 5, the Sobol' sampler (at $(el) s)"
  /tmp/render $lr/scene.json -o /tmp/x.png --backend gpu --schedule wavefront --walk-stage on \
    --estimator nee --rr-depth $rr --sampler sobol --environment-guide off \
    --bvh-preset quality --spp $sp --bounces 10 --size $ss -q --no-bloom \
    --stats $R/stages-nee-sobol.json > /dev/null 2>&1 || echo "render: exit $?"
  kernels $R/stages-nee-sobol.json "nee, sobol sampler" || true
  for r in 1 2; do
    echo "== shadow stage off/on, NEE + roulette 5, round $r (at $(el) s)"
    timeout 200 /tmp/bench --backend gpu --spp $sp --size $ss --repeat 3 --schedule wavefront --reorder off \
      --bvh wide --walk-stage on --shadow-stage off,on --estimator nee --rr-depth $rr \
      --json $R/shadow-$r.json $lr/scene.json scenes/teapot.toml scenes/cornell-box.toml \
      > $R/shadow-$r.md 2> $R/shadow-$r.log || echo "bench: exit $?"
    awk '/^\| scene \| prims \| spp/{p=1} /^$/{p=0} p' $R/shadow-$r.md
  done
  fi
  if [[ $parts == *" parts "* ]]; then
  echo "== issue 16: whole renders against 4 parts in separate processes, 1000x1000, 100 spp (at $(el) s)"
  local sc k i
  for sc in scenes/cornell-box.toml scenes/living-room/scene.json; do
    local tag; tag=$(basename "$(dirname "$sc")")-$(basename "$sc" .toml)
    for k in 1 2; do
      timeout 60 /tmp/render $sc -o /tmp/whole.exr --backend gpu --size 1000x1000 --spp 100 \
        --stats $R/parts-$tag-whole-$k.json -q 2>&1 | grep -E '^raylume: trace' | sed "s|^|$tag whole $k: |"
    done
    timeout 60 /tmp/render $sc -o /tmp/gpus.exr --backend gpus --size 1000x1000 --spp 100 \
      --stats $R/parts-$tag-gpus.json -q 2>&1 | grep -E '^raylume: trace' | sed "s|^|$tag gpus (1 device): |"
    for i in 1 2 3 4; do
      timeout 60 /tmp/render $sc -o /tmp/part-$i.exr --backend gpu --size 1000x1000 --spp 100 --part $i/4 \
        --stats $R/parts-$tag-part-$i.json -q 2>&1 | grep -E '^raylume: trace' | sed "s|^|$tag part $i/4: |"
    done
    TIMEFORMAT="$tag merge of 4 parts: %R s"
    time (/tmp/merge -o /tmp/merged.exr /tmp/part-1.exr /tmp/part-2.exr /tmp/part-3.exr /tmp/part-4.exr 2>&1 | tail -1)
  done
  fi
  if [[ $parts == *" two-gpus "* ]]; then
  # Issue 17 (not in the default set): each scene rendered on one GPU and split over every GPU
  # of the machine (`--backend gpus`), T1_GPUS_SIZE (1000x1000), 10 bounces, T1_GPUS_SPP (1000)
  # spp, the library's defaults, T1_GPUS_ROUNDS (3) rounds of a process per backend; the
  # speed-up of the best traces, each GPU's share and trace seconds (the stats' `workers`), and
  # every round's split image against its one-GPU image within raylume::merge_bound
  # (`compare --merge-bound`). On a one-GPU machine it measures what splitting costs there.
  local gsize=${T1_GPUS_SIZE:-1000x1000} gspp=${T1_GPUS_SPP:-1000} gsc gtag k b
  echo "== issue 17: one GPU against --backend gpus over $(nvidia-smi -L | wc -l) GPUs, $gsize, $gspp spp (at $(el) s)"
  nvidia-smi -L || true
  # How the GPUs are linked (NVLink or PCIe): the split's merge reads each device's sums back.
  nvidia-smi topo -m > "$R/gpus-topology.txt" 2>&1 || true
  for gsc in scenes/living-room/scene.json scenes/cornell-box.toml; do
    gtag=$(basename "$gsc" | sed 's/\.[a-z]*$//'); [ "$gtag" = scene ] && gtag=$(basename "$(dirname "$gsc")")
    for k in $(seq 1 "${T1_GPUS_ROUNDS:-3}"); do
      for b in gpu gpus; do
        rm -f "/tmp/$gtag-$b.exr"
        timeout 300 /tmp/render "$gsc" -o "/tmp/$gtag-$b.exr" --backend $b --size "$gsize" \
          --spp "$gspp" --bounces 10 --stats "$R/gpus-$gtag-$b-$k.json" -q \
          > "$R/gpus-$gtag-$b-$k.log" 2>&1 || echo "$gtag $b, round $k: exit $?"
        grep -E '^raylume: trace|error' "$R/gpus-$gtag-$b-$k.log" | sed "s|^|$gtag $b, round $k: |" || true
      done
      /tmp/compare "/tmp/$gtag-gpus.exr" "/tmp/$gtag-gpu.exr" --merge-bound "$gspp" --blocks 0 \
        2>&1 | grep -E 'worst relative|error' | sed "s|^|$gtag round $k, gpus against gpu: |" || true
    done
    python3 - "$R" "$gtag" "${T1_GPUS_ROUNDS:-3}" <<'EOP'
import json, sys
R, tag, rounds = sys.argv[1], sys.argv[2], int(sys.argv[3])
def load(b, k):
    try:
        return json.load(open(f"{R}/gpus-{tag}-{b}-{k}.json"))
    except OSError:
        return None
one = [s for s in (load("gpu", k) for k in range(1, rounds + 1)) if s]
split = [s for s in (load("gpus", k) for k in range(1, rounds + 1)) if s]
if not one or not split:
    print(f"{tag}: no stats to summarise"); sys.exit(0)
t1 = min(s["seconds"]["trace"] for s in one)
best = min(split, key=lambda s: s["seconds"]["trace"])
tn = best["seconds"]["trace"]
print(f"{tag}: one GPU {t1:.4f} s, split over {len(best['workers'])} {tn:.4f} s: "
      f"speed-up {t1 / tn:.2f}x (best traces of {len(one)} and {len(split)} processes)")
for i, w in enumerate(best["workers"]):
    smp = w.get("samples") or {}
    print(f"  worker {i} ({w['adapter']}): samples {smp.get('begin')}..{smp.get('end')}, "
          f"trace {w['trace_seconds']:.4f} s, total {w['total_seconds']:.4f} s")
EOP
  done
  fi
  if [[ $parts == *" large "* ]]; then
  echo "== issue 19: the ${T1_GRID:-1224}^2-quad grid from file to a 10-spp PNG (at $(el) s)"
  # T1_ROUNDS rounds (default 2); in each a process per BVH builder in T1_BUILDERS (default
  # "auto"; `render --bvh-builder`), then Mitsuba's. The first round compiles.
  local g=/tmp/grid n=${T1_GRID:-1224} b k
  SIZES=$n MAKE_GRID=/tmp/make_grid bash .gpu/large.sh make $g > /dev/null
  ls -la $g | tail -2
  for k in $(seq 1 ${T1_ROUNDS:-2}); do
    for b in ${T1_BUILDERS:-auto}; do
      TIMEFORMAT="raylume grid, builder $b, process $k: %R s"
      time (timeout 60 /tmp/render $g/grid-$n.toml -o /tmp/grid.png --backend gpu --spp 10 \
        --bvh-builder $b --stats $R/render-grid-$b-$k.json -q 2>&1 | grep -E '^raylume: trace')
    done
    TIMEFORMAT="mitsuba grid, process $k: %R s"
    time (PYTHONPATH=$m timeout 100 python3 .gpu/mitsuba_grid.py $g/grid-$n.obj $R/mitsuba-grid-$k.json \
      --variant cuda_ad_rgb --size 1000x1000 --spp 10 --png /tmp/grid-mi.png 2>&1 | tail -1)
  done
  fi
  if [[ $parts == *" builders "* ]]; then
  # The living room from file to a 10-spp PNG and at 100 spp, per BVH builder, T1_ROUNDS rounds.
  echo "== the living room per BVH builder (at $(el) s)"
  for k in $(seq 1 ${T1_ROUNDS:-2}); do
    for b in ${T1_BUILDERS:-auto}; do
      for spp in 10 100; do
        timeout 60 /tmp/render scenes/living-room/scene.json -o /tmp/lr-$b.png --backend gpu \
          --spp $spp --bvh-builder $b --stats $R/render-lr-$b-$spp-$k.json -q 2>&1 \
          | grep -E '^raylume: trace' | sed "s/^/$b $spp spp, round $k: /"
      done
    done
  done
  fi
  if [[ $parts == *" crossing "* ]]; then
  # Where the wavefront with its stages overtakes the persistent schedule as the samples grow
  # (Tracer::schedule's default, WAVEFRONT_MIN_SAMPLES): T1_CROSSING_SPP on the large scenes
  # (T1_CROSSING_SCENES), 1000x1000, 10 bounces, both estimators.
  local est
  for est in plain nee; do
    echo "== crossing, $est (at $(el) s)"
    timeout 240 /tmp/bench --backend gpu --spp ${T1_CROSSING_SPP:-1,2,3,4,6,10,100} --repeat 3 \
      --schedule persistent,wavefront --reorder off --bvh wide --walk-stage on --estimator $est \
      $([ $est = nee ] && echo --rr-depth $rr) --json $R/crossing-$est.json \
      ${T1_CROSSING_SCENES:-scenes/living-room/scene.json scenes/teapot.toml scenes/glass-teapot.toml} \
      > $R/crossing-$est.md 2> $R/crossing-$est.log || echo "bench: exit $?"
    awk '/^\| scene \| prims \| spp/{p=1} /^$/{p=0} p' $R/crossing-$est.md
  done
  fi
  if [[ $parts == *" race "* ]]; then
  # The living room from its file to a 10-spp PNG (its own 1280x720, 64 bounces), raylume with
  # the library's default schedule and with --schedule persistent, against Mitsuba's load +
  # first render: T1_RACE_ROUNDS cold rounds (every process fresh cache directories: the
  # driver's shader cache, Dr.Jit's and OptiX's), then warm ones (a directory per arm, whose
  # round 0 fills it). raylume: `total` of its stats (device opening and PNG included);
  # Mitsuba: load_s + first_render_s (its import and PNG not counted).
  local arm k
  race() { # arm, cache directory, tag
    local d=$2 j=$R/race-$3-$1.json
    # The NVIDIA driver writes its shader cache only into a directory that exists: without
    # $d/gl every raylume process compiled cold (the first race, 2026-12-05 on an H100).
    mkdir -p $d/gl $d/cache
    local envs="HOME=$d XDG_CACHE_HOME=$d/cache __GL_SHADER_DISK_CACHE_PATH=$d/gl OPTIX_CACHE_PATH=$d/optix CUDA_CACHE_PATH=$d/cuda"
    case $1 in
      mitsuba)
        env $envs PYTHONPATH=$m timeout 100 python3 .gpu/mitsuba_table1.py scenes/living-room $d/mi \
          --tungsten .gpu/tungsten.py --spp 1 --size 1280x720 --depth 65 > $d/mi.log 2>&1 || true
        cp $d/mi/living-room-mi-table1.json $j 2>/dev/null || true
        python3 -c "import json,sys; r=json.load(open('$j')); print('$3 mitsuba: %.3f s (load %.3f, first render %.3f)' % (r['load_s']+r['first_render_s'], r['load_s'], r['first_render_s']))" 2>/dev/null || echo "$3 mitsuba: failed"
        ;;
      *)
        env $envs timeout 60 /tmp/render scenes/living-room/scene.json -o $d/lr.png --backend gpu \
          --spp 10 $([ $1 = persistent ] && echo --schedule persistent) --stats $j -q > /dev/null 2>&1 || true
        python3 -c "import json; r=json.load(open('$j')); s=r['seconds']; print('$3 $1: %.3f s (trace %.4f, %s)' % (s['total'], s['trace'], r['schedule']))" 2>/dev/null || echo "$3 $1: failed"
        ;;
    esac
  }
  echo "== the living room from file to a 10-spp PNG, cold (at $(el) s)"
  for k in $(seq 1 ${T1_RACE_ROUNDS:-4}); do
    for arm in default persistent mitsuba; do race $arm /tmp/race-cold-$k-$arm cold-$k; done
  done
  echo "== warm (at $(el) s)"
  for k in $(seq 0 ${T1_RACE_ROUNDS:-4}); do
    for arm in default persistent mitsuba; do race $arm /tmp/race-warm-$arm warm-$k; done
  done
  fi
}

case "$mode" in
  stage) stage ;;
  *) device ;;
esac
