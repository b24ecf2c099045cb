#!/usr/bin/env bash
# Issue 19's large-scene measurement: height-field grids written as OBJ (examples/make_grid.rs),
# rendered by raylume's `render` and by Mitsuba 3 (tools/large/mitsuba_grid.py) from the same
# file, one after the other in one run, each in a fresh process, best of REPS.
#
#   tools/large/large.sh make [DIR]          grids of 100k, 1M and 3M triangles + their TOML scenes
#   tools/large/large.sh local [DIR]         the CPU table (raylume --backend cpu, Mitsuba llvm_ad_rgb)
#
# Env: SIZES (quads per side, default "224 707 1224"), REPS (default 3), SIZE (image, default
# 128x128), SPP (default 4), RENDER (the render binary, default target/release/examples/render),
# MITSUBA (a folder holding Mitsuba's trimmed `mitsuba` and `drjit` packages; default: unpacked
# from .mitsuba-local/mitsuba-trim.tar.xz, made by `PYVER=3.11 ../shared/peers/mitsuba/pack.sh
# .mitsuba-local`), DRJIT_LIBLLVM_PATH (libLLVM for llvm_ad_rgb; default Debian's libllvm19).
# Writes DIR/large.md (the table) and DIR/large.jsonl (every run: raylume's --stats JSON and
# Mitsuba's timings, with peak memory from /usr/bin/time).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
cmd=${1:?usage: large.sh make|local [DIR]}
dir=${2:-/tmp/raylume-large}
SIZES=${SIZES:-"224 707 1224"}
REPS=${REPS:-3}
SIZE=${SIZE:-128x128}
SPP=${SPP:-4}
RENDER=${RENDER:-$root/target/release/examples/render}
mkdir -p "$dir"

# The scene raylume renders: the grid (unit square, heights within +-0.07) seen from above at
# an angle, grey diffuse 0.8 under a constant white sky. mitsuba_grid.py builds the same.
toml() {
  cat <<TOML
# issue 19's grid, $1 (written by tools/large/large.sh)
[camera]
position = [0.5, 0.6, 1.6]
look_at = [0.5, 0.0, 0.5]
up = [0.0, 1.0, 0.0]
vfov = 40.0

[render]
width = 1000
height = 1000
spp = 10
max_bounces = 10

[environment]
radiance = [1.0, 1.0, 1.0]

[materials.grey]
type = "diffuse"
albedo = [0.8, 0.8, 0.8]

[[mesh]]
file = "$1"
material = "grey"
TOML
}

case $cmd in
make)
  make_grid=${MAKE_GRID:-$root/target/release/examples/make_grid}
  for n in $SIZES; do
    [ -s "$dir/grid-$n.obj" ] || "$make_grid" "$n" "$dir/grid-$n.obj"
    toml "grid-$n.obj" > "$dir/grid-$n.toml"
  done
  ;;
local)
  if [ -z "${MITSUBA:-}" ]; then
    MITSUBA=$(mktemp -d)
    tar -C "$MITSUBA" -xJf "$root/.mitsuba-local/mitsuba-trim.tar.xz"
  fi
  export DRJIT_LIBLLVM_PATH=${DRJIT_LIBLLVM_PATH:-/usr/lib/x86_64-linux-gnu/libLLVM-19.so}
  : > "$dir/large.jsonl"
  for n in $SIZES; do
    for r in $(seq "$REPS"); do
      /usr/bin/time -f '%M' -o "$dir/rss" "$RENDER" "$dir/grid-$n.toml" -o "$dir/grid-$n.png" \
        --backend cpu --size "$SIZE" --spp "$SPP" --stats "$dir/stats.json" -q 2>> "$dir/render.log"
      python3 -c "import json,sys; d=json.load(open(sys.argv[1])); d['peer']='raylume'; d['grid']=int(sys.argv[2]); d['peak_kb']=int(open(sys.argv[3]).read().split()[-1]); print(json.dumps(d))" \
        "$dir/stats.json" "$n" "$dir/rss" >> "$dir/large.jsonl"
      /usr/bin/time -f '%M' -o "$dir/rss" env PYTHONPATH="$MITSUBA" python3 "$root/tools/large/mitsuba_grid.py" \
        "$dir/grid-$n.obj" "$dir/mi.json" --variant llvm_ad_rgb --size "$SIZE" --spp "$SPP" --png "$dir/grid-$n-mi.png" > /dev/null
      python3 -c "import json,sys; d=json.load(open(sys.argv[1])); d['peer']='mitsuba'; d['grid']=int(sys.argv[2]); d['peak_kb']=int(open(sys.argv[3]).read().split()[-1]); print(json.dumps(d))" \
        "$dir/mi.json" "$n" "$dir/rss" >> "$dir/large.jsonl"
    done
  done
  python3 "$root/tools/large/table.py" "$dir/large.jsonl" | tee "$dir/large.md"
  ;;
*) echo "large.sh: unknown command $cmd (make or local)" >&2; exit 2 ;;
esac
