#!/bin/sh
# Renders a scene across a Slurm cluster: a job array of N render parts (`render --part I/N`,
# one task each, on whatever nodes Slurm gives them) and a merge job that runs once every
# part has succeeded (`--dependency=afterok`), writing the image of one render of all the
# samples. POSIX sh (Slurm runs batch scripts with /bin/sh).
#
#   examples/slurm/submit.sh SCENE OUT.(exr|png) N [render flags...]
#
# Environment: RAYLUME_BIN (the folder holding the `render` and `merge` binaries, default
# target/release/examples; build them with `cargo build --release --example render --example
# merge`), PARTS_DIR (where the parts go, default OUT's folder + /OUT-parts; it must be on a
# file system every node sees), SBATCH_ARGS (more sbatch options for both jobs, e.g.
# "--partition=gpu --gres=gpu:1"). Prints "ARRAY_JOB_ID MERGE_JOB_ID" on stdout; the logs are
# in PARTS_DIR. The merged image is bit for bit or within raylume::merge_bound of a single
# render (crates/raylume/src/parts.rs).
set -eu
if [ $# -lt 3 ]; then
  echo "usage: submit.sh SCENE OUT.(exr|png) N [render flags...]" >&2
  exit 2
fi
scene=$1; out=$2; n=$3; shift 3
case $n in ''|*[!0-9]*) echo "submit.sh: N must be a whole number, not '$n'" >&2; exit 2 ;; esac
[ "$n" -ge 1 ] || { echo "submit.sh: N must be at least 1" >&2; exit 2; }
[ -f "$scene" ] || { echo "submit.sh: no scene file $scene" >&2; exit 2; }
bin=${RAYLUME_BIN:-target/release/examples}
for b in render merge; do
  [ -x "$bin/$b" ] || { echo "submit.sh: no $bin/$b (cargo build --release --example render --example merge)" >&2; exit 2; }
done
abs() { case $1 in /*) echo "$1" ;; *) echo "$(pwd)/$1" ;; esac; }
scene=$(abs "$scene"); out=$(abs "$out"); bin=$(abs "$bin")
parts=$(abs "${PARTS_DIR:-${out%.*}-parts}")
mkdir -p "$parts"
# The render flags, quoted for the job scripts.
flags=""
for a in "$@"; do flags="$flags '$(printf %s "$a" | sed "s/'/'\\\\''/g")'"; done

array=$(sbatch --parsable ${SBATCH_ARGS:-} --job-name=raylume-part --array=1-"$n" \
  -o "$parts/part-%a.log" --wrap "\"$bin/render\" \"$scene\" --part \$SLURM_ARRAY_TASK_ID/$n -o \"$parts/part-\$SLURM_ARRAY_TASK_ID.exr\" -q $flags")
list=""
i=1
while [ "$i" -le "$n" ]; do list="$list \"$parts/part-$i.exr\""; i=$((i + 1)); done
merge=$(sbatch --parsable ${SBATCH_ARGS:-} --job-name=raylume-merge --dependency=afterok:"$array" \
  -o "$parts/merge.log" --wrap "\"$bin/merge\" -o \"$out\" $list")
echo "$array $merge"
