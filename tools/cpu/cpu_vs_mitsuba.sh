#!/usr/bin/env bash
# Issue 15's equal-spp comparison on this machine's CPU: raylume's CPU path and Mitsuba 3's
# `llvm_ad_rgb`, back to back in one run, ROUNDS rounds (ratios within one run only: the VM's
# speed drifts between runs, Mitsuba's JIT-compiled code more than raylume's).
#
#   tools/cpu/cpu_vs_mitsuba.sh [OUT]      (from the project's root; OUT: /tmp/cpu-vs-mitsuba)
#
# Needs Mitsuba 3 for Python (`PYVER=3.11 ../shared/peers/mitsuba/pack.sh .mitsuba-local`,
# extracted to $MITSUBA, default /tmp/mitsuba) and libLLVM ($DRJIT_LIBLLVM_PATH, default
# Debian 12's libllvm19). Settings: SIZE (1000x1000), SPP (10), ROUNDS (2), TARGET_CPU (unset:
# the default target, what a dependent's release build gets, whose CPU path runs at the CPU's
# best instruction-set level since 7e661ca (`raylume_kernels::cpu::isa`); `native`: raylume
# built with `-C target-cpu=native`, as Mitsuba's JIT compiles for the host); 10 bounces
# (Mitsuba's max_depth 11); RR (4): the segment where the equal-spp rows begin Russian
# roulette (below); BEST (3): the equal-spp criterion's two raylume renders (the
# Cornell box, the living room with the guide off) are each the best of BEST renders, as
# Mitsuba's are the best of 3 after a warm-up (`tungsten.py`, `mitsuba_table1.py`; until
# session 42 raylume's were one render, set against Mitsuba's best of 3); the other rows (guide
# on, the independent sampler) stay one render; CORNELL_ONLY=1 times the Cornell box's row alone
# (more rounds in less time). Each round then times the issue's equal-error criterion:
# Bitterli's Cornell box at 128x128, Mitsuba at 64 spp with each of two samplers, timed with
# the sampler whose error it sets (`tools/study/mitsuba_series.py`: a warm-up, then best of
# 3): `multijitter` (the lower error) against raylume at EQ_SPP (65), and `independent`
# (Mitsuba's default) against raylume at EQ_SPP_DEFAULT (40); raylume best of 3. The spp are
# where raylume's image (seed 0, the script's) is below Mitsuba's 64-spp error scored against
# either renderer's 4096-spp reference (docs/study/cpu-8a62220-equal-error.md: multijitter
# 1.617e-3 / 1.665e-3, raylume at 65 spp 1.564e-3 / 1.601e-3, at 64 1.650e-3 / 1.644e-3;
# independent 3.338e-3 / 3.370e-3, raylume at 40 spp 3.099e-3 / 3.068e-3). (Until session
# 31, EQ_SPP was 69, from errors against 2048-spp references each renderer scored alone, and
# light samples chosen by a number of another net; until session 29 the part set the
# multijitter error against the independent sampler's time, 5-12 % less than its own.)
#
# The scenes: Bitterli's Cornell box (`tungsten.py` on Mitsuba's side) and raylume's copy of
# the living room (`tools/table1/mitsuba_table1.py`: its constant sky as a `constant` emitter).
# raylume renders with its library defaults (NEE + MIS, the `sobol` sampler) but for where
# Russian roulette begins: at equal spp from segment RR (default 4), which is where Mitsuba's
# `path` (NEE + MIS, its default rr_depth 5, its independent sampler) begins it. Mitsuba counts
# a path's hits from 1 and tests `depth >= rr_depth` after incrementing (path.cpp; its docs:
# with rr_depth 1 a path "may randomly cease after encountering directly visible surfaces"),
# so its first roulette follows its 5th hit, raylume's segment 4 (segments count from 0, the
# camera ray's). Until session 46 raylume's rows took its default, 5: a segment later than
# Mitsuba, 10-14 % more segments in the living room. The equal-error rows keep the default
# (raylume's best error per second, docs/ACCURACY.md). The
# living room twice: with `--environment-guide off`, the estimator that matches Mitsuba's (the
# sky sampled by its radiance alone: for a constant sky, uniformly), and with `on` (what `auto`
# picks for a render this size: shadow rays aimed where the sky is visible, fewer of them
# blocked early, so each costs more). Both scenes once more with `--sampler independent`, as
# Mitsuba's (raylume's `sobol` costs more per sample and, at 128x128, reaches a given error in
# fewer samples: the equal-error part keeps it).
set -euo pipefail
OUT=${1:-/tmp/cpu-vs-mitsuba}
SIZE=${SIZE:-1000x1000}
SPP=${SPP:-10}
ROUNDS=${ROUNDS:-2}
EQ_SPP=${EQ_SPP:-65}
EQ_SPP_DEFAULT=${EQ_SPP_DEFAULT:-40}
BEST=${BEST:-3}
RR=${RR:-4}
CORNELL_ONLY=${CORNELL_ONLY:-0}
CB=../shared/scenes-external/bitterli-cornell-box
LR=scenes/living-room
mkdir -p "$OUT"
. tools/cpu/common.sh
if [ -n "${TARGET_CPU:-}" ]; then
  # raylume built for TARGET_CPU (e.g. native: Mitsuba's LLVM JIT compiles for the host's),
  # in a target directory of its own; the release build's flags are the crate's dependents'.
  CARGO_TARGET_DIR=target/cpu-$TARGET_CPU RUSTFLAGS="-C target-cpu=$TARGET_CPU" \
    cargo build --release --example render -q
  R=target/cpu-$TARGET_CPU/release/examples/render
else
  cargo build --release --example render -q
  R=target/release/examples/render
fi
echo "# $(date -u +%FT%TZ) commit $(git rev-parse --short HEAD)$(git diff --quiet || echo '+dirty')," \
  "$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(nproc) CPUs;" \
  "$SIZE, $SPP spp, 10 bounces; raylume's equal-spp rows best of $BEST, roulette from segment $RR; raylume built for ${TARGET_CPU:-the default target (x86-64)}" | tee "$OUT/summary.md"

# raylume's trace seconds of one render (its closing line): NAME SIZE SPP ARGS...
raylume() {
  "$R" --backend cpu --size "$2" --spp "$3" --bounces 10 -q -o "$OUT/$1.png" "${@:4}" 2>&1 |
    sed -n 's/^raylume: trace \([0-9.]*\) s.*/\1/p'
}
# The equal-spp criterion's rows: the best of BEST (Mitsuba's side: best of 3 after a warm-up).
raylume_best() {
  best_of "$BEST" raylume "$@"
}
mitsuba_cb() {
  PYTHONPATH=$MITSUBA "$PY" ../shared/peers/mitsuba/tungsten.py "$CB" "$OUT" llvm_ad_rgb \
    --size "$1" --spp "$2" --depth 11 2>/dev/null | sed -n "s/.*spp $2: \([0-9.]*\) s/\1/p"
}
# Mitsuba's 64-spp seconds with sampler $1 from mitsuba_series.py's record (below).
mi64() {
  "$PY" -c 'import json, sys; print(json.load(open(sys.argv[1]))["times"]["64"])' \
    "$OUT/mi/$(basename "$CB")-mi-series-$1.json"
}
for r in $(seq "$ROUNDS"); do
  cb=$(raylume_best cornell "$SIZE" "$SPP" --rr-depth "$RR" "$CB/scene.json")
  if [ "$CORNELL_ONLY" = 1 ]; then
    mcb=$(mitsuba_cb "$SIZE" "$SPP")
    awk -v r="$r" -v cb="$cb" -v mcb="$mcb" 'BEGIN {
      printf "round %d: Cornell box raylume %.2f s, Mitsuba %.2f s (%.2fx its time)\n", r, cb, mcb, cb / mcb }' |
      tee -a "$OUT/summary.md"
  else
    lr_off=$(raylume_best living-room-guide-off "$SIZE" "$SPP" --rr-depth "$RR" --environment-guide off "$LR/scene.json")
    lr_on=$(raylume living-room-guide-on "$SIZE" "$SPP" --rr-depth "$RR" --environment-guide on "$LR/scene.json")
    # Mitsuba's own random numbers too (its `independent` sampler): the estimator exactly.
    cb_ind=$(raylume cornell-independent "$SIZE" "$SPP" --rr-depth "$RR" --sampler independent "$CB/scene.json")
    lr_ind=$(raylume living-room-independent "$SIZE" "$SPP" --rr-depth "$RR" --environment-guide off --sampler independent "$LR/scene.json")
    mcb=$(mitsuba_cb "$SIZE" "$SPP")
    mlr=$(mitsuba_scene "$LR" "$SIZE" "$SPP" 11)
    awk -v r="$r" -v cb="$cb" -v mcb="$mcb" -v off="$lr_off" -v on="$lr_on" -v mlr="$mlr" \
      -v cbi="$cb_ind" -v lri="$lr_ind" 'BEGIN {
      printf "round %d: Cornell box raylume %.2f s, Mitsuba %.2f s (%.2fx its time); ", r, cb, mcb, cb / mcb
      printf "living room raylume %.2f s guide off (%.2fx its time), %.2f s guide on (%.2fx), Mitsuba %.2f s\n",
        off, off / mlr, on, on / mlr, mlr
      printf "round %d: with the independent sampler (Mitsuba'"'"'s): Cornell box %.2f s (%.2fx its time), living room guide off %.2f s (%.2fx)\n",
        r, cbi, cbi / mcb, lri, lri / mlr }' | tee -a "$OUT/summary.md"
  fi
  eq=$(best_of 3 raylume cornell-128 128x128 "$EQ_SPP" "$CB/scene.json")
  eqd=$(best_of 3 raylume cornell-128-default 128x128 "$EQ_SPP_DEFAULT" "$CB/scene.json")
  rm -rf "$OUT/mi"
  PYTHONPATH=$MITSUBA "$PY" tools/study/mitsuba_series.py "$CB" "$OUT/mi" --size 128x128 --spp 64 \
    --samplers multijitter,independent --depth 11 --variant llvm_ad_rgb \
    --tungsten ../shared/peers/mitsuba/tungsten.py >/dev/null 2>&1
  mmj=$(mi64 multijitter)
  mind=$(mi64 independent)
  awk -v r="$r" -v eq="$eq" -v eqd="$eqd" -v mmj="$mmj" -v mind="$mind" -v s="$EQ_SPP" -v sd="$EQ_SPP_DEFAULT" 'BEGIN {
    printf "round %d: equal error, Cornell box 128x128: raylume %d spp %.3f s (best of 3) against Mitsuba multijitter 64 spp %.3f s: %.2fx its time; ",
      r, s, eq, mmj, eq / mmj
    printf "raylume %d spp %.3f s against Mitsuba independent (its default) 64 spp %.3f s: %.2fx\n",
      sd, eqd, mind, eqd / mind }' | tee -a "$OUT/summary.md"
done
