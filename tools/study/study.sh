#!/usr/bin/env bash
# The error-versus-time study (issue 20, item 5): relative MSE against a converged reference
# versus seconds for every knob that trades accuracy for time, raylume (examples/study.rs) and
# Mitsuba 3 (mitsuba_series.py) on the same axes. See tools/study/README.md.
#
#   tools/study/study.sh stage                          # here: build, strip, fill .gpu/
#   . .gl/on-device.sh && bash .gpu/study-device.sh     # there (the device tool's run)
#   tools/study/study.sh local                          # here: the raylume CPU study, small
#   tools/study/study.sh plot RESULTS.jsonl... DIR      # here: SVGs and the table from results
#
# Settings (environment), with the defaults of device / local mode:
#   STUDY_SIZE      500x500 / 128x128          image size
#   STUDY_BOUNCES   10                         raylume bounces; Mitsuba's max_depth is this + 1
#   STUDY_SCENES    Bitterli's Cornell box and scenes/living-room / the Cornell box only
#                   (folders, each with a scene.json)
#   STUDY_REF_SPP   "16384 8192" / "2048"      raylume's reference spp, one per scene
#   STUDY_MI_REF_SPP  "16384 8192" / -         Mitsuba's reference spp, one per scene
#   STUDY_SPP       4,16,64,256,1024 / 4,16,64,256   raylume's spp per configuration
#   STUDY_MI_SPP    4,16,64,256,1024 / -       Mitsuba's spp per sampler
#   STUDY_MI_SAMPLERS  multijitter,independent Mitsuba's samplers
#   STUDY_KNOBS     spp,bounces,estimator,rr,sampler,batch,reorder / the same less reorder
#                   (the CPU never sorts rays)
#   STUDY_BASELINE  (empty: nee, sobol, rr 5, batch 20, reorder off) study's --baseline
#   STUDY_EXTRA     more flags for `study run` (e.g. "--bounces-list 1,3 --batch-list 5,64")
#   STUDY_BACKEND   gpu / cpu                  raylume's --backend
#   STUDY_VARIANT   cuda_ad_rgb                Mitsuba's variant
#   STUDY_MAX_RENDER_S  4 / 20                 a configuration stops going up in spp after a
#                                              render this slow
#   STUDY_BUDGET_S  400 / 0                    start no new step after this many seconds (a
#                                              step: one scene's Mitsuba run, then its raylume
#                                              run, which gets the rest of the budget as its
#                                              --budget-s)
#   STUDY_PLOT_TIMES  wall / "wall cpu"       the time axes plotted (cpu: CPU seconds of all
#                                              threads, for the CPU backend on a shared machine)
#   STUDY_BIN, STUDY_MITSUBA_PY, STUDY_TUNGSTEN  (device) an unpacked study binary, Mitsuba
#                   site folder and tungsten.py instead of the staged ones (to try device
#                   mode elsewhere, with STUDY_BACKEND=cpu STUDY_VARIANT=scalar_rgb)
#   STUDY_NO_BUILD  (local) skip the cargo build
#   OUT             results (device: the tool's $OUT; local: /tmp/study-local)
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
mode=${1:-}
[ $# -gt 0 ] && shift

die() { echo "study.sh: $*" >&2; exit 1; }
start=$(date +%s)
elapsed() { echo $(($(date +%s) - start)); }
# over_budget STEP: true (and logged) when past STUDY_BUDGET_S.
over_budget() {
  if [ "${STUDY_BUDGET_S:-0}" -gt 0 ] && [ "$(elapsed)" -gt "$STUDY_BUDGET_S" ]; then
    echo "SKIPPED: $1 (past STUDY_BUDGET_S=$STUDY_BUDGET_S s, at $(elapsed) s)" >&2
    return 0
  fi
  return 1
}

# One scene: raylume's reference and configurations, then (if MITSUBA_PY is set) Mitsuba's
# series and reference, and every Mitsuba EXR scored against both references.
# Needs: STUDY (the binary), work, the STUDY_* settings; MITSUBA_SERIES, TUNGSTEN for Mitsuba.
study_scene() {
  local dir=$1 ref_spp=$2 mi_ref_spp=${3:-} name t0 mitsuba=
  name=$(basename "$dir")
  [ -f "$dir/scene.json" ] || die "$dir/scene.json not found"
  local rl_ref=$work/$name-raylume-ref.exr
  # Mitsuba first (about a minute a scene): its curves are what raylume is judged against, so a
  # run cut short by the budget should lose raylume's last repeats rather than them.
  if [ -n "${MITSUBA_PY:-}" ] && [ -n "$mi_ref_spp" ] && ! over_budget "Mitsuba $name"; then
    t0=$(date +%s)
    if PYTHONPATH=$MITSUBA_PY python3 "$MITSUBA_SERIES" "$dir" "$work/mi" --tungsten "$TUNGSTEN" \
      --variant "$STUDY_VARIANT" --size "$STUDY_SIZE" --depth $((STUDY_BOUNCES + 1)) \
      --spp "$STUDY_MI_SPP" --samplers "$STUDY_MI_SAMPLERS" --ref "$mi_ref_spp"; then
      mitsuba=1
    else
      echo "FAILED: Mitsuba $name" >&2
    fi
    echo "Mitsuba $name: $(($(date +%s) - t0)) s (at $(elapsed) s)" >&2
  fi
  if ! over_budget "raylume $name"; then
    t0=$(date +%s)
    # The rest of the budget, for `study run` itself: it starts no configuration and no repeat
    # pass after it (what it measured is still written).
    local budget=()
    [ "${STUDY_BUDGET_S:-0}" -gt 0 ] && budget=(--budget-s $((STUDY_BUDGET_S - $(elapsed))))
    # shellcheck disable=SC2086
    "$STUDY" run "$dir/scene.json" --name "$name" --size "$STUDY_SIZE" --bounces "$STUDY_BOUNCES" \
      --make-reference "$ref_spp" --reference "$rl_ref" --spp "$STUDY_SPP" --knobs "$STUDY_KNOBS" \
      --baseline "$STUDY_BASELINE" --backend "$STUDY_BACKEND" --max-render-s "$STUDY_MAX_RENDER_S" \
      --out "$OUT/results.jsonl" --csv "$OUT/results.csv" --pictures "$work/pictures" \
      --commit "$COMMIT" "${budget[@]}" $STUDY_EXTRA || echo "FAILED: raylume $name" >&2
    echo "raylume $name: $(($(date +%s) - t0)) s (at $(elapsed) s)" >&2
  fi
  [ -n "$mitsuba" ] || return 0
  # Every Mitsuba EXR against Mitsuba's reference and against raylume's.
  local s mi_ref
  mi_ref=$(ls "$work/mi/$name"-mi-ref-*.exr 2>/dev/null | head -1)
  for s in ${STUDY_MI_SAMPLERS//,/ }; do
    local series=$work/mi/$name-mi-series-$s.json
    [ -f "$series" ] || continue
    [ -n "$mi_ref" ] && "$STUDY" mitsuba "$series" --reference "$mi_ref" --reference-kind own \
      --scene-name "$name" --adapter "$STUDY_VARIANT on $GPU_NAME" \
      --out "$OUT/results.jsonl" --csv "$OUT/results.csv"
    [ -f "$rl_ref" ] && "$STUDY" mitsuba "$series" --reference "$rl_ref" --reference-kind raylume \
      --scene-name "$name" --adapter "$STUDY_VARIANT on $GPU_NAME" \
      --out "$OUT/results.jsonl" --csv "$OUT/results.csv"
  done
  # The two references against each other: how far apart the renderers' converged images are
  # (scored as a one-point "series": the floor under Mitsuba's curves against raylume's
  # reference).
  if [ -n "$mi_ref" ] && [ -f "$rl_ref" ]; then
    local x=$work/mi/xref
    mkdir -p "$x"
    cp "$mi_ref" "$x/$name-mi-reference-$mi_ref_spp.exr"
    printf '{"scene": "%s", "sampler": "reference", "depth": %d, "times": {"%d": 0}}\n' \
      "$name" $((STUDY_BOUNCES + 1)) "$mi_ref_spp" >"$x/$name-xref.json"
    "$STUDY" mitsuba "$x/$name-xref.json" --exr-dir "$x" --reference "$rl_ref" \
      --reference-kind raylume-ref-vs-mitsuba-ref --scene-name "$name" \
      --adapter "$STUDY_VARIANT on $GPU_NAME" --out "$OUT/results.jsonl" || true
  fi
  return 0
}

# $OUT from the work folder: results (already there), the plots and table, pictures, log.
publish() {
  [ -f "$OUT/results.jsonl" ] || return 0
  rm -rf "$work/plots" && mkdir -p "$work/plots"
  local t
  for t in ${STUDY_PLOT_TIMES:-wall}; do
    "$STUDY" plot "$OUT/results.jsonl" --out-dir "$work/plots" --time "$t" \
      --table "$OUT/table$([ "$t" = wall ] || echo "-$t").md" \
      >/dev/null 2>>"$work/log.txt" || echo "plot --time $t failed (see log.txt)" >&2
  done
  (cd "$work" && tar -czf "$OUT/study-plots.tar.gz" plots $( [ -d pictures ] && echo pictures))
  cp "$work/log.txt" "$OUT/log.txt" 2>/dev/null || true
}

study_all() {
  : "${STUDY_BOUNCES:=10}" "${STUDY_BASELINE:=}" "${STUDY_EXTRA:=}"
  : "${STUDY_MI_SAMPLERS:=multijitter,independent}" "${STUDY_VARIANT:=cuda_ad_rgb}"
  mkdir -p "$OUT"
  work=$(mktemp -d)
  local dirs refs mirefs i
  read -r -a dirs <<<"$STUDY_SCENES"
  read -r -a refs <<<"$STUDY_REF_SPP"
  read -r -a mirefs <<<"${STUDY_MI_REF_SPP:-}"
  [ ${#dirs[@]} -eq ${#refs[@]} ] || die "STUDY_SCENES and STUDY_REF_SPP need one entry per scene"
  {
    echo "study: raylume $COMMIT, $(date -u '+%Y-%m-%d %H:%M UTC'), $GPU_NAME"
    echo "size $STUDY_SIZE, $STUDY_BOUNCES bounces, spp $STUDY_SPP, knobs $STUDY_KNOBS, backend $STUDY_BACKEND"
  } | tee -a "$work/log.txt" >&2
  for i in "${!dirs[@]}"; do
    study_scene "${dirs[$i]}" "${refs[$i]}" "${mirefs[$i]:-}" 2>&1 | tee -a "$work/log.txt" >&2
    echo "after $(basename "${dirs[$i]}"): $(elapsed) s" | tee -a "$work/log.txt" >&2
    publish
  done
  rm -rf "$work"
  echo "results in $OUT: $(cd "$OUT" && ls | tr '\n' ' ')" >&2
  cat "$OUT/table.md" 2>/dev/null || true
}

case $mode in
stage)
  root=$(git -C "$here" rev-parse --show-toplevel)
  cd "$root"
  shared=$(cd "$root/../shared" && pwd)
  [ -f .gl/on-device.sh ] || die "run $shared/gpu/prepare.sh once first (it fills .gl/)"
  cargo build --release --example study
  # The binary travels xz-compressed. The living room is not copied: the device machine gets
  # the working tree and reads scenes/living-room there; the Cornell box lives outside the
  # repository, so it is copied (tools/agree uses the same .gpu/scenes/ copy).
  tmp=$(mktemp -d)
  mkdir -p "$tmp/bin" .gpu/scenes
  cp target/release/examples/study "$tmp/bin/study" && strip "$tmp/bin/study"
  tar -C "$tmp" -cJf .gpu/study-bin.tar.xz bin
  rm -rf "$tmp" .gpu/scenes/bitterli-cornell-box
  cp -r "$shared/scenes-external/bitterli-cornell-box" .gpu/scenes/
  install -m 644 "$shared/peers/mitsuba/tungsten.py" .gpu/tungsten.py
  install -m 644 tools/study/study.sh tools/study/mitsuba_series.py .gpu/
  [ -f .gpu/mitsuba-trim.tar.xz ] || "$shared/peers/mitsuba/pack.sh" .gpu
  cat >.gpu/study-device.sh <<'EOS'
#!/usr/bin/env bash
# Written by tools/study/study.sh stage: the error-versus-time study on the lent GPU.
exec bash "$(dirname "${BASH_SOURCE[0]}")/study.sh" device "$@"
EOS
  c=$(git rev-parse --short HEAD)
  git status --porcelain --untracked-files=no | grep -q . && c="$c+changes" &&
    echo "(working tree has changes: the binary is of HEAD + those)" >&2
  echo "$c" >.gpu/study-commit.txt
  total=$(du -sk .gpu .gl | awk '{s += $1} END {print int(s / 1024)}')
  echo "staged into .gpu/: .gpu/ and .gl/ hold $total MiB of the 64 MiB the device tool carries:"
  du -sh .gpu/* | sed 's/^/  /'
  [ "$total" -lt 63 ] || echo "WARNING: over the carry limit: ask whoever staged the other files before removing any" >&2
  echo "on the lent GPU: run with carry [\".gl\", \".gpu\"] and the command"
  echo "  . .gl/on-device.sh && bash .gpu/study-device.sh"
  ;;
device)
  # Runs from the project root of the device machine's copy, $here = .gpu.
  : "${OUT:?device mode writes to \$OUT}"
  root=$(cd "$here/.." && pwd)
  : "${STUDY_SIZE:=500x500}" "${STUDY_SPP:=4,16,64,256,1024}" "${STUDY_MI_SPP:=4,16,64,256,1024}"
  : "${STUDY_SCENES:=$here/scenes/bitterli-cornell-box $root/scenes/living-room}"
  : "${STUDY_REF_SPP:=16384 8192}" "${STUDY_MI_REF_SPP:=16384 8192}"
  : "${STUDY_KNOBS:=spp,bounces,estimator,rr,sampler,batch,reorder}"
  : "${STUDY_BACKEND:=gpu}" "${STUDY_MAX_RENDER_S:=4}" "${STUDY_BUDGET_S:=400}"
  # STUDY_BIN / STUDY_MITSUBA_PY: an unpacked binary / Mitsuba instead of the staged packs (to
  # try device mode elsewhere, e.g. with STUDY_BACKEND=cpu STUDY_VARIANT=scalar_rgb).
  if [ -n "${STUDY_BIN:-}" ]; then
    STUDY=$STUDY_BIN
  else
    bin=$(mktemp -d)
    tar -C "$bin" -xJf "$here/study-bin.tar.xz"
    STUDY=$bin/bin/study
  fi
  MITSUBA_SERIES=$here/mitsuba_series.py TUNGSTEN=${STUDY_TUNGSTEN:-$here/tungsten.py}
  if [ -n "${STUDY_MITSUBA_PY:-}" ]; then
    MITSUBA_PY=$STUDY_MITSUBA_PY
  else
    MITSUBA_PY=$(mktemp -d)
    tar -C "$MITSUBA_PY" -xJf "$here/mitsuba-trim.tar.xz"
  fi
  COMMIT=$(cat "$here/study-commit.txt" 2>/dev/null || echo '?')
  GPU_NAME=$(nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null | head -1 || true)
  : "${GPU_NAME:=unknown GPU}"
  study_all
  ;;
local)
  root=$(git -C "$here" rev-parse --show-toplevel)
  cd "$root"
  shared=$(cd "$root/../shared" && pwd)
  : "${OUT:=/tmp/study-local}"
  : "${STUDY_SIZE:=128x128}" "${STUDY_SPP:=4,16,64,256}"
  : "${STUDY_SCENES:=$shared/scenes-external/bitterli-cornell-box}" "${STUDY_REF_SPP:=2048}"
  : "${STUDY_KNOBS:=spp,bounces,estimator,rr,sampler,batch}"
  : "${STUDY_BACKEND:=cpu}" "${STUDY_MAX_RENDER_S:=20}" "${STUDY_BUDGET_S:=0}"
  # CPU seconds too: on a machine shared with other work they are steadier than wall time.
  : "${STUDY_PLOT_TIMES:=wall cpu}"
  export STUDY_PLOT_TIMES
  [ -n "${STUDY_NO_BUILD:-}" ] || cargo build --release --example study
  STUDY=$root/target/release/examples/study
  COMMIT=$(git rev-parse --short HEAD)
  git status --porcelain --untracked-files=no | grep -q . && COMMIT="$COMMIT+changes"
  GPU_NAME="no GPU (CPU backend)"
  MITSUBA_PY=  # the local study is raylume's alone (Mitsuba: tools/agree's local mode)
  export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp/xdg}
  mkdir -p "$XDG_RUNTIME_DIR"
  rm -f "$OUT/results.jsonl" "$OUT/results.csv"
  study_all
  ;;
plot)
  [ $# -ge 2 ] || die "usage: study.sh plot RESULTS.jsonl... OUT_DIR"
  root=$(git -C "$here" rev-parse --show-toplevel)
  outdir=${*: -1}
  files=("${@:1:$#-1}")
  "$root/target/release/examples/study" plot "${files[@]}" --out-dir "$outdir" --table "$outdir/table.md"
  ;;
*)
  sed -n '2,/^set -euo/p' "$0" | grep '^#' | sed 's/^# \{0,1\}//'
  [ -z "$mode" ] || [ "$mode" = help ] || exit 2
  ;;
esac
