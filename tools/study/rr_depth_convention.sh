#!/usr/bin/env bash
# Which raylume `--rr-depth` is Mitsuba 3's `path` at a given `rr_depth`? A roulette that can
# only act after a path's last segment leaves the image bit for bit as with roulette off;
# one that acts before it changes it. So each renderer renders a tiny Cornell box with the
# roulette's start one below and at the path's length, and says which start changes the
# image. Mitsuba (max_depth b + 1 = raylume's --bounces b): rr_depth b changes it, b + 1 does
# not; raylume: --rr-depth b - 1 changes it, b does not. Mitsuba's rr_depth k is raylume's
# --rr-depth k - 1 (Mitsuba counts hits from 1, raylume segments from 0): its default 5 is 4.
#
#   tools/study/rr_depth_convention.sh        (from the project's root; a release `render`)
#
# Needs Mitsuba 3 for Python at $MITSUBA (default /tmp/mitsuba; see tools/cpu/cpu_vs_mitsuba.sh)
# and numpy for /usr/bin/python3.
set -euo pipefail
MITSUBA=${MITSUBA:-/tmp/mitsuba}
export DRJIT_LIBLLVM_PATH=${DRJIT_LIBLLVM_PATH:-/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1}
CB=../shared/scenes-external/bitterli-cornell-box/scene.json
OUT=$(mktemp -d)
cargo build --release --example render -q
for b in 1 2 3; do
  for rr in $((b - 1)) $b off; do
    target/release/examples/render --backend cpu --size 64x64 --spp 4 --bounces $b \
      --rr-depth $rr -q -o "$OUT/raylume-$b-$rr.exr" "$CB" > /dev/null 2>&1
  done
  for rr in $((b - 1)) $b; do
    if cmp -s "$OUT/raylume-$b-$rr.exr" "$OUT/raylume-$b-off.exr"; then s="the same as off"; else s="changed"; fi
    echo "raylume --bounces $b --rr-depth $rr: image $s"
  done
done
PYTHONPATH=$MITSUBA /usr/bin/python3 - <<'PY'
import mitsuba as mi, numpy as np
mi.set_variant('llvm_ad_rgb')
base = mi.cornell_box()
base['sensor']['film']['width'] = base['sensor']['film']['height'] = 64
base['sensor']['sampler']['sample_count'] = 4
def render(max_depth, rr):
    d = dict(base)
    d['integrator'] = {'type': 'path', 'max_depth': max_depth, 'rr_depth': rr}
    return np.array(mi.render(mi.load_dict(d), seed=0))
# Mitsuba's film sums a pixel's samples in no fixed order (its threads' scatter-adds): two
# renders of one setting may differ by float rounding (a first draft of this script, comparing
# bit for bit, once saw rr_depth 3 at max_depth 3 "changed"; rerun, every such pair was equal).
# A roulette that acts moves pixels by ~1e-3 and more; 1e-5 tells the two apart.
for b in (1, 2, 3):
    off = render(b + 1, 1000)
    floor = np.abs(render(b + 1, 1000) - off).max()
    for rr in (b, b + 1):
        d = np.abs(render(b + 1, rr) - off).max()
        s = 'the same as off' if d < 1e-5 else 'changed'
        print(f"Mitsuba max_depth {b + 1} (--bounces {b}) rr_depth {rr}: image {s} "
              f"(largest pixel difference {d:.2g}; off against itself {floor:.2g})")
PY
rm -rf "$OUT"
