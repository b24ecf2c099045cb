#!/usr/bin/env bash
# Where issue 15's living-room gap lies: raylume's CPU path and Mitsuba 3 `llvm_ad_rgb` back to
# back, by depth and with the materials taken out (docs/study/cpu-3fe4505-where-the-gap-lies.md).
#
#   tools/cpu/gap_by_depth.sh [OUT]      (from the project's root; OUT: /tmp/gap-by-depth)
#
# Renders, each round: the living room at 10 bounces, then an all-diffuse copy of it (every
# BSDF a `lambert` of its own constant albedo, 0.5 where that was a texture; the same meshes
# and sky, written to OUT/lr-diffuse) at each of BOUNCES (default "0 3 10"; Mitsuba's
# max_depth is one more). raylume best of 3 (`--rr-depth 4 --environment-guide off`, the
# criterion's estimator), Mitsuba best of 3 after a warm-up (`mitsuba_table1.py`). SIZE
# (1000x1000), SPP (10), ROUNDS (2); MITSUBA, PYTHON, DRJIT_LIBLLVM_PATH: tools/cpu/common.sh.
# Between two depths it also prints what the segments between them cost each renderer (the
# difference of two noisy renders each: read it over rounds).
set -euo pipefail
OUT=${1:-/tmp/gap-by-depth}
SIZE=${SIZE:-1000x1000}
SPP=${SPP:-10}
ROUNDS=${ROUNDS:-2}
BOUNCES=${BOUNCES:-0 3 10}
LR=scenes/living-room
. tools/cpu/common.sh
mkdir -p "$OUT/lr-diffuse"
ln -sfn "$PWD/$LR/models" "$OUT/lr-diffuse/models"
ln -sfn "$PWD/$LR/textures" "$OUT/lr-diffuse/textures"
"$PY" - "$LR/scene.json" "$OUT/lr-diffuse/scene.json" <<'PYEOF'
import json, sys
scene = json.load(open(sys.argv[1]))
for i, b in enumerate(scene['bsdfs']):
    albedo = b.get('albedo', 0.5)
    if not isinstance(albedo, (int, float, list)):
        albedo = 0.5
    scene['bsdfs'][i] = {'name': b['name'], 'albedo': albedo, 'type': 'lambert'}
json.dump(scene, open(sys.argv[2], 'w'), indent=1)
PYEOF
cargo build --release --example render -q
R=target/release/examples/render
# raylume's trace seconds and segment rate: NAME SCENE_DIR BOUNCES
raylume_once() {
  "$R" --backend cpu --size "$SIZE" --spp "$SPP" --bounces "$3" --rr-depth 4 \
    --environment-guide off -q -o "$OUT/$1.png" "$2/scene.json" 2>&1 |
    sed -n 's/^raylume: trace \([0-9.]*\) s, \([0-9.]*\) Mrays.*/\1 \2/p'
}
# The best of three such renders (the least seconds): NAME SCENE_DIR BOUNCES
raylume() { best_of 3 raylume_once "$@"; }
# Mitsuba's best seconds: SCENE_DIR MAX_DEPTH
mitsuba() { mitsuba_scene "$1" "$SIZE" "$SPP" "$2"; }
row() { # LABEL "SECONDS RATE" MITSUBA_SECONDS
  awk -v l="$1" -v r="$2" -v m="$3" 'BEGIN { split(r, a, " ");
    printf "%s: raylume %.3f s (%.1f M segments), Mitsuba %.3f s: %.2fx its time\n", l, a[1], a[1] * a[2], m, a[1] / m }'
}
# What the segments between two depths cost each renderer: LABEL "SECONDS RATE" MITSUBA
# (the deeper row) "SECONDS RATE" MITSUBA (the shallower one).
step() {
  awk -v l="$1" -v r="$2" -v m="$3" -v r0="$4" -v m0="$5" 'BEGIN { split(r, a, " "); split(r0, b, " ");
    d = m - m0; ratio = d > 0 ? sprintf("%.2fx", (a[1] - b[1]) / d) : "no ratio (Mitsuba not slower deeper: noise)";
    printf "%s: raylume +%.3f s (+%.1f M segments), Mitsuba +%.3f s: %s\n", l, a[1] - b[1], a[1] * a[2] - b[1] * b[2], d, ratio }'
}
echo "# $(date -u +%FT%TZ) commit $(git rev-parse --short HEAD)$(git diff --quiet || echo '+dirty'), $(nproc) CPUs; $SIZE, $SPP spp" | tee "$OUT/summary.md"
for r in $(seq "$ROUNDS"); do
  row "round $r living room, 10 bounces" "$(raylume lr "$LR" 10)" "$(mitsuba "$LR" 11)" | tee -a "$OUT/summary.md"
  prev=
  for b in $BOUNCES; do
    ry=$(raylume "lrd$b" "$OUT/lr-diffuse" "$b")
    mi=$(mitsuba "$OUT/lr-diffuse" $((b + 1)))
    row "round $r all-diffuse copy, $b bounces" "$ry" "$mi" | tee -a "$OUT/summary.md"
    if [ -n "$prev" ]; then
      step "round $r all-diffuse copy, segments $((prev + 1))-$b" "$ry" "$mi" "$prev_ry" "$prev_mi" |
        tee -a "$OUT/summary.md"
    fi
    prev=$b prev_ry=$ry prev_mi=$mi
  done
done
