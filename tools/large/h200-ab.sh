#!/usr/bin/env bash
# Issue 19's H200 comparison as an A/B of two builds, in one device call: the 3M grid and the
# living room from file to a 10-spp PNG, raylume "before" and "after" and Mitsuba 3
# (`cuda_ad_rgb`: load + first render) alternating, each in a fresh process.
#
#   here:  fill .gpu/ with render.xz (after), render-before.xz, make_grid.xz (stripped, xz'd
#          release binaries), mitsuba-trim.tar.xz (../shared/peers/mitsuba/pack.sh, the
#          device's Python), tungsten.py, tools/table1/mitsuba_table1.py,
#          tools/large/{mitsuba_grid.py,large.sh}, commits.txt (a line naming the two), and
#          this script; then the device tool's run with carry [".gl", ".gpu"]:
#   there: . .gl/on-device.sh && bash .gpu/h200-ab.sh
#
# GRID_ROUNDS (default 4) and LR_ROUNDS (default 6). Results: $OUT/r.tgz (every --stats JSON,
# Mitsuba's JSON), a summary printed last. Used for docs/study/h200-ec1388d-large.md.
set -uo pipefail
cd "$(dirname "$0")/.."
R=/tmp/r; rm -rf $R; mkdir -p $R
trap 'tar czf "$OUT/r.tgz" -C '$R' .' EXIT
for b in render-before render make_grid; do xz -dc .gpu/$b.xz > /tmp/$b && chmod +x /tmp/$b; done
mv /tmp/render /tmp/render-after
m=$(mktemp -d); tar -C "$m" -xJf .gpu/mitsuba-trim.tar.xz
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}
cat .gpu/commits.txt | tee $R/commits.txt
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee $R/gpu.txt
nproc | tee -a $R/gpu.txt
g=/tmp/grid; SIZES=1224 MAKE_GRID=/tmp/make_grid bash .gpu/large.sh make $g > /dev/null
for k in $(seq "${GRID_ROUNDS:-4}"); do
  for b in before after; do
    TIMEFORMAT="grid round $k, $b: process %R s"
    time (timeout 60 /tmp/render-$b $g/grid-1224.toml -o /tmp/grid-$b.png --backend gpu --spp 10 \
      --stats $R/grid-$b-$k.json -q 2>&1 | grep -E '^raylume: trace' | cut -c1-200)
  done
  TIMEFORMAT="grid round $k, mitsuba: process %R s"
  time (PYTHONPATH=$m timeout 100 python3 .gpu/mitsuba_grid.py $g/grid-1224.obj $R/mitsuba-grid-$k.json \
    --variant cuda_ad_rgb --size 1000x1000 --spp 10 --png /tmp/grid-mi.png 2>&1 | tail -1)
done
cmp /tmp/grid-before.png /tmp/grid-after.png && echo "grid: same PNG before and after"
for k in $(seq "${LR_ROUNDS:-6}"); do
  for b in before after; do
    TIMEFORMAT="lr round $k, $b: process %R s"
    time (/tmp/render-$b scenes/living-room/scene.json -o /tmp/lr-$b.png --backend gpu --spp 10 \
      --stats $R/lr-$b-$k.json -q 2>&1 | grep -E '^raylume: trace' | cut -c1-200)
  done
  TIMEFORMAT="lr round $k, mitsuba: process %R s"
  time (PYTHONPATH=$m python3 .gpu/mitsuba_table1.py scenes/living-room /tmp/mi$k \
    --tungsten .gpu/tungsten.py --spp 1 --size 1280x720 --depth 65 > /tmp/mi$k.log 2>&1 || true)
  cp /tmp/mi$k/*.json $R/mitsuba-lr-$k.json 2>/dev/null || true
  grep -iE "load|render" /tmp/mi$k.log | tail -2
done
cmp /tmp/lr-before.png /tmp/lr-after.png && echo "living room: same PNG before and after"
python3 - "$R" <<'PY'
import json,glob,sys,os
R=sys.argv[1]
for scene in ['grid','lr']:
    for b in ['before','after']:
        t=[]
        for f in sorted(glob.glob(f'{R}/{scene}-{b}-*.json')):
            d=json.load(open(f)); s=d['seconds']; t.append((s['total'],s['load'],s['bvh'],s['upload'],s['trace']))
        print(scene,b,'total',[round(x[0],3) for x in t],'load',[round(x[1],3) for x in t],'bvh',[round(x[2],3) for x in t])
PY
