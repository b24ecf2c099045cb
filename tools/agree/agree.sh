#!/usr/bin/env bash
# The agreement harness (issue 11, part 4): renders Tungsten scenes (scene.json) with raylume
# and with Mitsuba 3, each as two independent halves, and compares them with
# examples/compare.rs: the ratio of the image means, the errors of 8x8-pixel block means
# (fraction within 3 %, p95, worst blocks) and, from the halves, what the same statistics
# would be from noise alone. See tools/agree/README.md.
#
#   tools/agree/agree.sh stage            # here: build, strip, fill .gpu/ for the lent GPU
#   . .gl/on-device.sh && bash .gpu/agree-device.sh   # there (the device tool's run)
#   tools/agree/agree.sh local            # here: the same comparison on the CPU, small
#
# Settings (environment), with the defaults of device / local mode:
#   AGREE_SIZES     "128x128 500x500 320x180" / "64x64"   image sizes
#   AGREE_RL_SPP    "32768 24576 16384" / "2048"   raylume spp per size, in all (two halves,
#                                                  seeds 1 and 2)
#   AGREE_MI_SPP    "16384 12288 8192" / "2048"    Mitsuba spp per size, in all (two halves)
#   AGREE_SCENES    scene folders, each with a scene.json: Bitterli's Cornell box and
#                   scenes/living-room (device: their copies in .gpu/scenes/)
#   AGREE_ESTIMATOR nee                      raylume's --estimator
#   AGREE_BOUNCES   10                       raylume's --bounces; Mitsuba's max_depth is this + 1
#   AGREE_BACKEND   gpu / cpu                raylume's --backend
#   AGREE_VARIANT   cuda_ad_rgb / llvm_ad_rgb   Mitsuba's variant (scalar_rgb also works)
#   AGREE_EXTRA     more flags for raylume's render (e.g. "--reorder on --schedule wavefront")
#   AGREE_TOL 0.03, AGREE_FLOOR 0.1          compare's --block-tolerance, --block-floor
#   AGREE_BUDGET_S  420 / 0                  start no further scene after this many seconds
#   AGREE_RENDER    (local) another raylume render binary to judge, e.g. an older build
#   AGREE_TEST      raylume | mitsuba: "mitsuba" judges a second, independent Mitsuba (other
#                   seeds, raylume's spp) instead of raylume: the instrument's self-check,
#                   which must PASS
#   AGREE_NO_BUILD  (local) skip the cargo build;  AGREE_KEEP: keep the work folder
#   OUT             results (device: the tool's $OUT; local: /tmp/agree-local)
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
mode=${1:-}
[ $# -gt 0 ] && shift

die() { echo "agree.sh: $*" >&2; exit 1; }
now_ms() { date +%s%3N; }
since() { local d=$(($(now_ms) - $1)); printf '%d.%03d' $((d / 1000)) $((d % 1000)); }

# One scene at every size: raylume halves, Mitsuba halves, compare, all into $work.
# Needs: BIN (render, compare), MITSUBA_PY (PYTHONPATH holding mitsuba), MITSUBA_REF,
# TUNGSTEN, and the AGREE_* settings.
compare_scene() {
  local dir=$1 name sizes rl mi runs=() i size
  name=$(basename "$dir")
  read -r -a sizes <<<"$AGREE_SIZES"
  read -r -a rl <<<"$AGREE_RL_SPP"
  read -r -a mi <<<"$AGREE_MI_SPP"
  [ ${#sizes[@]} -eq ${#rl[@]} ] && [ ${#sizes[@]} -eq ${#mi[@]} ] ||
    die "AGREE_SIZES, AGREE_RL_SPP and AGREE_MI_SPP need one entry per size"
  local t0 spps tests=() tname=raylume
  mitsuba() { # TAG SEED SPP...: Mitsuba halves at every size
    local tag=$1 seed=$2 runs=() k
    shift 2
    spps=("$@")
    for k in "${!sizes[@]}"; do runs+=("${sizes[$k]}:${spps[$k]}"); done
    t0=$(now_ms)
    PYTHONPATH=$MITSUBA_PY python3 "$MITSUBA_REF" "$dir" "$work" --tungsten "$TUNGSTEN" \
      --variant "$AGREE_VARIANT" --depth $((AGREE_BOUNCES + 1)) --tag "$tag" --seed "$seed" \
      --runs "$(IFS=,; echo "${runs[*]}")" ${AGREE_MI_CHUNK:+--chunk-samples $AGREE_MI_CHUNK} ||
      die "Mitsuba ($tag) failed on $name"
    echo "$tag $name: $(since "$t0") s wall for all sizes (import, load, JIT included)" >&2
  }
  mitsuba mitsuba 0 "${mi[@]}"
  # The self-check: the test is a second, independent Mitsuba (other seeds) at raylume's spp.
  if [ "${AGREE_TEST:-raylume}" = mitsuba ]; then
    tname=mitsuba-self
    mitsuba mitsuba-self 50000000 "${rl[@]}"
  fi
  for i in "${!sizes[@]}"; do
    size=${sizes[$i]}
    local case=$name-$size half=$((rl[i] / 2)) batch=()
    [ $((rl[i] % 2)) -eq 0 ] && [ "$half" -ge 1 ] || die "raylume spp ${rl[$i]}: must be even"
    if [ "$tname" = raylume ]; then
      # Small images: more samples per batch keep the GPU busy (same image expectation).
      local w=${size%x*} h=${size#*x}
      [ $((w * h)) -lt 100000 ] && [ "$AGREE_BACKEND" = gpu ] && batch=(--batch-spp 64)
      for s in a:1 b:2; do
        t0=$(now_ms)
        "$RENDER" "$dir/scene.json" -o "$work/$case-raylume-${s%:*}.exr" \
          --backend "$AGREE_BACKEND" --size "$size" --spp "$half" --bounces "$AGREE_BOUNCES" \
          --estimator "$AGREE_ESTIMATOR" --seed "${s#*:}" --no-bloom -q "${batch[@]}" \
          --stats "$work/$case-raylume-${s%:*}.stats.json" $AGREE_EXTRA 2>"$work/$case-raylume-${s%:*}.log" ||
          { cat "$work/$case-raylume-${s%:*}.log" >&2; die "raylume failed on $case"; }
        echo "raylume $case half ${s%:*}: $half spp, $(since "$t0") s wall" >&2
      done
    fi
    local args=("$work/$case-$tname-a.exr" "$work/$case-mitsuba-a.exr"
      --test2 "$work/$case-$tname-b.exr" --reference2 "$work/$case-mitsuba-b.exr"
      --blocks 8 --block-tolerance "$AGREE_TOL" --block-floor "$AGREE_FLOOR")
    "$BIN/compare" "${args[@]}" --block-image "$work/$case-blocks.png" >"$work/$case-compare.txt" ||
      die "compare failed on $case"
    "$BIN/compare" "${args[@]}" --json >"$work/$case-compare.json" || die "compare failed on $case"
    {
      if [ "$tname" = raylume ]; then
        echo "== $case: raylume ${rl[$i]} spp ($AGREE_BACKEND, $AGREE_ESTIMATOR) vs Mitsuba ${mi[$i]} spp ($AGREE_VARIANT)"
      else
        echo "== $case: self-check, Mitsuba ${rl[$i]} spp (other seeds) vs Mitsuba ${mi[$i]} spp ($AGREE_VARIANT)"
      fi
      cat "$work/$case-compare.txt"
    } >&2
  done
}

# Writes $OUT from the work folder: summary.md / summary.json, log.txt and two tarballs (the
# device tool brings back at most 8 files): agree-results.tar.gz (compare's JSON and text, the
# block images, render's stats and logs, Mitsuba's timings) and agree-exr.tar.gz (the halves,
# reusable as references; tiers: every EXR, else all but raylume's large ones, else the sizes
# up to 256x256 only, whichever first stays under 15 MiB).
publish() {
  python3 "$SUMMARY" "$work" --tolerance "$AGREE_TOL" --json "$OUT/summary.json" >"$OUT/summary.md"
  (cd "$work" && tar -czf "$OUT/agree-results.tar.gz" $(ls ./*.json ./*.txt ./*.png ./*.log 2>/dev/null))
  local exrs tier
  rm -f "$OUT/agree-exr.tar.gz"
  for tier in all mitsuba small; do
    exrs=$(cd "$work" && ls ./*.exr 2>/dev/null | python3 -c '
import sys, re
tier = sys.argv[1]
for f in sys.stdin.read().split():
    m = re.search(r"-(\d+)x(\d+)-(raylume|mitsuba)-", f)
    big = m is not None and int(m.group(1)) * int(m.group(2)) > 65536
    if tier == "all" or (tier == "mitsuba" and (not big or m.group(3) == "mitsuba")) or (tier == "small" and not big):
        print(f)' "$tier")
    [ -n "$exrs" ] || break
    (cd "$work" && tar -czf "$OUT/agree-exr.tar.gz" $exrs)
    [ "$(stat -c %s "$OUT/agree-exr.tar.gz")" -gt $((15 * 1024 * 1024)) ] || break
    rm -f "$OUT/agree-exr.tar.gz"
  done
  [ -f "$OUT/agree-exr.tar.gz" ] && echo "$tier" >"$work/exr-tier.txt"
  cp "$work/log.txt" "$OUT/log.txt"
}

# Runs every scene (publishing $OUT after each, so that a run cut short still reports what
# it finished), then prints the table.
compare_all() {
  : "${AGREE_ESTIMATOR:=nee}" "${AGREE_BOUNCES:=10}" "${AGREE_TOL:=0.03}" "${AGREE_FLOOR:=0.1}"
  : "${AGREE_EXTRA:=}" "${AGREE_BUDGET_S:=0}" "${RENDER:=$BIN/render}"
  mkdir -p "$OUT"
  work=$(mktemp -d)
  local start dir failed=0
  start=$(date +%s)
  for dir in $AGREE_SCENES; do
    if [ "$AGREE_BUDGET_S" -gt 0 ] && [ $(($(date +%s) - start)) -gt "$AGREE_BUDGET_S" ]; then
      echo "SKIPPED: $dir (past AGREE_BUDGET_S=$AGREE_BUDGET_S s)" | tee -a "$work/log.txt" >&2
      failed=1; continue
    fi
    [ -f "$dir/scene.json" ] || die "$dir/scene.json not found"
    # A scene that fails is logged and skipped: the others still report.
    compare_scene "$dir" 2>&1 | tee -a "$work/log.txt" >&2 ||
      { echo "FAILED: $dir (see log.txt)" | tee -a "$work/log.txt" >&2; failed=1; }
    echo "after $(basename "$dir"): $(($(date +%s) - start)) s" | tee -a "$work/log.txt" >&2
    publish
  done
  publish
  echo "results in $OUT: $(cd "$OUT" && ls | tr '\n' ' ')" >&2
  [ -n "${AGREE_KEEP:-}" ] && echo "work files kept in $work" >&2 || rm -rf "$work"
  cat "$OUT/summary.md"
  return $failed
}

case $mode in
stage)
  root=$(git -C "$here" rev-parse --show-toplevel)
  cd "$root"
  shared=$(cd "$root/../shared" && pwd)
  [ -f .gl/on-device.sh ] || die "run $shared/gpu/prepare.sh once first (it fills .gl/)"
  cargo build --release --example render --example compare
  # The binaries travel xz-compressed (14 MB stripped, 4 MB packed). The living room is not
  # copied: the device machine gets the working tree (tracked files) and reads
  # scenes/living-room from it; the Cornell box lives outside the repository, so it is copied.
  tmp=$(mktemp -d)
  mkdir -p "$tmp/bin" .gpu/scenes
  for b in render compare; do
    cp target/release/examples/$b "$tmp/bin/$b" && strip "$tmp/bin/$b"
  done
  tar -C "$tmp" -cJf .gpu/agree-bin.tar.xz bin
  rm -rf "$tmp" .gpu/bin .gpu/scenes/living-room .gpu/scenes/bitterli-cornell-box
  cp -r "$shared/scenes-external/bitterli-cornell-box" .gpu/scenes/
  install -m 644 "$shared/peers/mitsuba/tungsten.py" .gpu/tungsten.py
  install -m 644 tools/agree/agree.sh tools/agree/mitsuba_ref.py tools/agree/summary.py .gpu/
  [ -f .gpu/mitsuba-trim.tar.xz ] || "$shared/peers/mitsuba/pack.sh" .gpu
  cat >.gpu/agree-device.sh <<'EOS'
#!/usr/bin/env bash
# Written by tools/agree/agree.sh stage: the agreement harness on the lent GPU.
exec bash "$(dirname "${BASH_SOURCE[0]}")/agree.sh" device "$@"
EOS
  git rev-parse --short HEAD >.gpu/agree-commit.txt
  git status --porcelain --untracked-files=no | grep -q . && echo "(working tree has changes: the binaries are of HEAD + those)" >&2
  total=$(du -sk .gpu .gl | awk '{s += $1} END {print int(s / 1024)}')
  echo "staged into .gpu/: .gpu/ and .gl/ hold $total MiB of the 64 MiB the device tool carries:"
  du -sh .gpu/* | sed 's/^/  /'
  others=$(cd .gpu && ls | grep -vxE 'agree-bin.tar.xz|agree-commit.txt|agree-device.sh|agree.sh|mitsuba_ref.py|summary.py|tungsten.py|mitsuba-trim.tar.xz|scenes' || true)
  [ -z "$others" ] || echo "  (not the harness's, left as they are: $(echo $others))"
  [ "$total" -lt 63 ] || echo "WARNING: over the carry limit: ask whoever staged the files above before removing any" >&2
  echo "on the lent GPU: run with carry [\".gl\", \".gpu\"] and the command"
  echo "  . .gl/on-device.sh && bash .gpu/agree-device.sh"
  ;;
device)
  # Runs from the project root of the device machine's copy, $here = .gpu.
  : "${OUT:?device mode writes to \$OUT}"
  # 320x180 is not in issue 11's criterion: a 16:9 size shows an error of the fov axis, which
  # square sizes cannot (their horizontal and vertical fov are the same).
  : "${AGREE_SIZES:=128x128 500x500 320x180}"
  : "${AGREE_RL_SPP:=32768 24576 16384}" "${AGREE_MI_SPP:=16384 12288 8192}"
  : "${AGREE_BUDGET_S:=420}"
  : "${AGREE_BACKEND:=gpu}" "${AGREE_VARIANT:=cuda_ad_rgb}"
  root=$(cd "$here/.." && pwd)
  : "${AGREE_SCENES:=$here/scenes/bitterli-cornell-box $root/scenes/living-room}"
  BIN=$(mktemp -d)
  tar -C "$BIN" -xJf "$here/agree-bin.tar.xz" && BIN=$BIN/bin
  MITSUBA_REF=$here/mitsuba_ref.py TUNGSTEN=$here/tungsten.py SUMMARY=$here/summary.py
  MITSUBA_PY=$(mktemp -d)
  tar -C "$MITSUBA_PY" -xJf "$here/mitsuba-trim.tar.xz"
  echo "raylume $(cat "$here/agree-commit.txt" 2>/dev/null || echo '?'); $(nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null | head -1)" >&2
  compare_all
  ;;
local)
  root=$(git -C "$here" rev-parse --show-toplevel)
  cd "$root"
  shared=$(cd "$root/../shared" && pwd)
  : "${OUT:=/tmp/agree-local}"
  : "${AGREE_SIZES:=64x64}" "${AGREE_RL_SPP:=2048}" "${AGREE_MI_SPP:=2048}"
  : "${AGREE_BACKEND:=cpu}" "${AGREE_VARIANT:=llvm_ad_rgb}" "${AGREE_MI_CHUNK:=16000000}"
  : "${AGREE_SCENES:=$shared/scenes-external/bitterli-cornell-box $root/scenes/living-room}"
  export AGREE_MI_CHUNK
  [ -n "${AGREE_NO_BUILD:-}" ] || cargo build --release --example render --example compare
  BIN=$root/target/release/examples RENDER=${AGREE_RENDER:-$root/target/release/examples/render}
  MITSUBA_REF=$here/mitsuba_ref.py SUMMARY=$here/summary.py
  TUNGSTEN=$shared/peers/mitsuba/tungsten.py
  MITSUBA_PY=$root/.mitsuba-local
  if [ ! -d "$MITSUBA_PY/mitsuba" ]; then
    [ -f "$MITSUBA_PY/mitsuba-trim.tar.xz" ] ||
      die "no local Mitsuba: PYVER=3.11 $shared/peers/mitsuba/pack.sh .mitsuba-local"
    tar -C "$MITSUBA_PY" -xJf "$MITSUBA_PY/mitsuba-trim.tar.xz"
  fi
  if [ "$AGREE_VARIANT" = llvm_ad_rgb ] && [ -z "${DRJIT_LIBLLVM_PATH:-}" ]; then
    DRJIT_LIBLLVM_PATH=$(dpkg -L libllvm19 2>/dev/null | grep 'libLLVM-19.so$' | head -1 || true)
    [ -n "$DRJIT_LIBLLVM_PATH" ] || die "llvm_ad_rgb needs libLLVM: apt-get install -y libllvm19 (or AGREE_VARIANT=scalar_rgb)"
    export DRJIT_LIBLLVM_PATH
  fi
  compare_all
  ;;
*)
  sed -n '2,/^set -euo/p' "$0" | grep '^#' | sed 's/^# \{0,1\}//'
  [ -z "$mode" ] || [ "$mode" = help ] || exit 2
  ;;
esac
