#!/usr/bin/env bash
# Converged references for every scene in scenes/ (issue 20, item 4), made by the study
# example's reference renderer (examples/study.rs `run --make-reference`): next-event
# estimation, the independent sampler, no Russian roulette, the scene's own bounces, rounds of
# 1,024 spp averaged in f64, seeds far from any test render's. One linear EXR per scene, and a
# references.jsonl line per scene (size, spp, seconds, adapter, commit) saying how it was made.
#
#   tools/references.sh OUT_DIR                  # here (builds the study example), or
#   STUDY=path/to/study tools/references.sh OUT  # with a built binary (the device machine)
#
# Settings (environment): REF_SIZE (default 500x500: every scene at that size; the EXRs are
# 3 MB each), REF_SPP (default 8192), REF_BACKEND (auto), REF_SCENES (default: every
# scenes/*.toml and scenes/living-room/scene.json). They are stored outside the repository
# (24 MB at the defaults); the README of OUT_DIR, written here, says how they were made.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
out=${1:?usage: tools/references.sh OUT_DIR}
mkdir -p "$out"
size=${REF_SIZE:-500x500}
spp=${REF_SPP:-8192}
backend=${REF_BACKEND:-auto}
if [ -z "${STUDY:-}" ]; then
  (cd "$root" && cargo build --release --example study)
  STUDY=$root/target/release/examples/study
fi
commit=${REF_COMMIT:-$(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)}
scenes=${REF_SCENES:-$(ls "$root"/scenes/*.toml) $root/scenes/living-room/scene.json}
for scene in $scenes; do
  name=$(basename "$scene" .toml)
  [ "$name" = scene.json ] && name=$(basename "$(dirname "$scene")")
  echo "reference $name: $size, $spp spp ($backend)" >&2
  # One baseline point at 1 spp comes with it (the study needs a configuration); it is cheap.
  "$STUDY" run "$scene" --name "$name" --size "$size" --make-reference "$spp" \
    --reference "$out/$name.exr" --knobs spp --spp 1 --repeats 1 --backend "$backend" \
    --commit "$commit" --out "$out/references.jsonl" >&2 ||
    echo "FAILED: $name" >&2
done
cat >"$out/README.md" <<EOT
Converged references of raylume's scenes/, made by \`tools/references.sh\` (raylume commit
$commit, $(date -u '+%Y-%m-%d %H:%M UTC')): $size, $spp spp each, next-event estimation, the
independent sampler, no Russian roulette, the scene's own bounces, rounds of 1,024 spp
averaged in f64 (examples/study.rs \`run --make-reference\`). Linear radiance, before bloom
and tone mapping. \`references.jsonl\`: one \`"kind": "reference"\` line per scene with its
size, spp, seconds and adapter.
EOT
ls -la "$out" >&2
