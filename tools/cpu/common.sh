# What tools/cpu's comparisons with Mitsuba 3 llvm share (sourced, not run): Mitsuba's and
# libLLVM's places, the best of several timings, and Mitsuba's render of a scene of raylume's
# (`tools/table1/mitsuba_table1.py`). Expects the caller's OUT, and `set -euo pipefail`.
#   MITSUBA: Mitsuba 3 for Python (`PYVER=3.11 ../shared/peers/mitsuba/pack.sh DIR`,
#   extracted; default /tmp/mitsuba); PYTHON (/usr/bin/python3); DRJIT_LIBLLVM_PATH (Debian
#   12's libllvm19).
MITSUBA=${MITSUBA:-/tmp/mitsuba}
PY=${PYTHON:-/usr/bin/python3}
export DRJIT_LIBLLVM_PATH=${DRJIT_LIBLLVM_PATH:-/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1}
[ -d "$MITSUBA/mitsuba" ] || {
  echo "$(basename "$0"): no Mitsuba at $MITSUBA (see tools/cpu/common.sh)" >&2
  exit 2
}

# The least of N runs of a command that prints a number (or a line that sorts by its first
# number): N COMMAND...
best_of() {
  local n=$1
  shift
  for _ in $(seq "$n"); do "$@"; done | sort -n | head -1
}

# Mitsuba llvm's best seconds (of 3, after a warm-up) on a Tungsten scene of raylume's (its
# constant sky as a `constant` emitter): SCENE_DIR SIZE SPP MAX_DEPTH
mitsuba_scene() {
  PYTHONPATH=$MITSUBA "$PY" tools/table1/mitsuba_table1.py "$1" "$OUT" \
    --tungsten ../shared/peers/mitsuba/tungsten.py --variant llvm_ad_rgb --size "$2" \
    --spp "$3" --depth "$4" 2>/dev/null | sed -n "s/^mitsuba .* spp $3: \([0-9.]*\) s/\1/p"
}
