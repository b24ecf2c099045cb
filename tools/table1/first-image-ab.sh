#!/usr/bin/env bash
# The living room from file to a 10-spp PNG, two raylume builds and Mitsuba 3 alternating in
# one device call (issues 13 and 19's first-image criterion, as an A/B of one change).
#
#   tools/table1/table1.sh stage                          # here: the current build, Mitsuba
#   tools/table1/first-image-ab.sh stage REV              # here: `render` of commit REV too
#   . .gl/on-device.sh && bash .gpu/first-image-ab.sh     # there (the device tool's run)
#
# AB_ROUNDS (default 4) rounds of: raylume before (REV), raylume after (the staged build),
# Mitsuba's load + first render (mitsuba_table1.py --spp 1, 10 spp, at the file's 1280x720
# and 64 bounces, the image raylume renders). Process 1 of each
# compiles; later ones find the driver's and Dr.Jit's caches. Each raylume process writes its
# `--stats` JSON; results in $OUT/ab.tgz.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
case ${1:-} in
stage)
  rev=${2:?a commit to compare with}
  root=$(git -C "$here" rev-parse --show-toplevel)
  w=$(mktemp -d)
  git -C "$root" worktree add --detach "$w" "$rev" >/dev/null
  (cd "$w" && CARGO_TARGET_DIR="$root/target/ab" cargo build --release -p raylume --example render)
  cp "$root/target/ab/release/examples/render" "$root/.gpu/render-before"
  strip "$root/.gpu/render-before" && xz -f -T2 "$root/.gpu/render-before"
  git -C "$w" rev-parse --short HEAD > "$root/.gpu/before.txt"
  git -C "$root" worktree remove --force "$w"
  cp "$here/first-image-ab.sh" "$root/.gpu/first-image-ab.sh"
  ;;
*)
  cd "$(dirname "$0")/.."
  R=/tmp/ab; rm -rf $R; mkdir -p $R
  trap 'tar czf "$OUT/ab.tgz" -C '$R' .' EXIT
  xz -dc .gpu/render-before.xz > /tmp/render-before; xz -dc .gpu/render.xz > /tmp/render-after
  chmod +x /tmp/render-before /tmp/render-after
  m=$(mktemp -d); tar -C "$m" -xJf .gpu/mitsuba-trim.tar.xz
  export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}
  echo "before $(cat .gpu/before.txt), after $(cat .gpu/commit.txt)" | tee $R/commits.txt
  nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee $R/gpu.txt
  for k in $(seq 1 "${AB_ROUNDS:-4}"); do
    for b in before after; do
      TIMEFORMAT="round $k, $b: process %R s"
      time (/tmp/render-$b scenes/living-room/scene.json -o /tmp/lr-$b.png --backend gpu --spp 10 \
        --stats $R/$b-$k.json -q 2>&1 | grep -E '^raylume: trace')
    done
    # Mitsuba renders the file as raylume does (its 1280x720 and 64 bounces: max_depth 65),
    # and, with AB_MI_TABLE1=1, also at Table 1's 1000x1000 and 10 bounces (the protocol of
    # the calls before 2026-12-03).
    TIMEFORMAT="round $k, mitsuba: process %R s"
    time (PYTHONPATH=$m python3 .gpu/mitsuba_table1.py scenes/living-room /tmp/mi$k \
      --tungsten .gpu/tungsten.py --spp 1 --size 1280x720 --depth 65 > /tmp/mi$k.log 2>&1 || true)
    head -1 /tmp/mi$k.log
    cp /tmp/mi$k/living-room-mi-table1.json $R/mitsuba-$k.json 2>/dev/null || true
    if [ "${AB_MI_TABLE1:-0}" = 1 ]; then
      TIMEFORMAT="round $k, mitsuba at 1000x1000, depth 11: process %R s"
      time (PYTHONPATH=$m python3 .gpu/mitsuba_table1.py scenes/living-room /tmp/mt$k \
        --tungsten .gpu/tungsten.py --spp 1 > /tmp/mt$k.log 2>&1 || true)
      head -1 /tmp/mt$k.log
      cp /tmp/mt$k/living-room-mi-table1.json $R/mitsuba-t1-$k.json 2>/dev/null || true
    fi
  done
  cmp /tmp/lr-before.png /tmp/lr-after.png && echo "the PNGs are the same" || echo "the PNGs differ"
  cp /tmp/lr-before.png /tmp/lr-after.png $R/
  ;;
esac
