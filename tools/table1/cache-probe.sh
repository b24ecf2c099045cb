#!/usr/bin/env bash
# Does the NVIDIA driver's shader disk cache serve raylume's pipelines in a second process? The
# living room from file to a 10-spp PNG, three processes sharing one cache directory (its gl/
# made first), three more with __GL_SHADER_DISK_CACHE_SKIP_CLEANUP=1, two with no cache
# variables. On the device (docs/study/h100-65834be-crossing-race.md, call 11):
#   tools/table1/table1.sh stage   # here; then copy this file into .gpu/ and run there:
#   . .gl/on-device.sh && bash .gpu/cache-probe.sh
set -u
xz -dc .gpu/render.xz > /tmp/render && chmod +x /tmp/render
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
show() { python3 -c "
import json,sys; r=json.load(open(sys.argv[1])); s=r['seconds']
print(sys.argv[2], ' '.join('%s %.3f' % (k, s[k]) for k in ('total','device','pipelines','upload','trace')), r['schedule'], 'ahead', r.get('pipelines_ahead'), 'wait', r.get('pipelines_wait'))" "$@"; }
probe() { # tag, extra env
  local d=/tmp/probe-$1; rm -rf $d; mkdir -p $d/gl
  for k in 1 2 3; do
    env HOME=$d XDG_CACHE_HOME=$d/cache __GL_SHADER_DISK_CACHE_PATH=$d/gl ${@:2} \
      timeout 60 /tmp/render scenes/living-room/scene.json -o /tmp/p.png --backend gpu --spp 10 \
      --stats /tmp/p-$1-$k.json -q > /tmp/p-$1-$k.log 2>&1 || { echo "exit $?"; tail -3 /tmp/p-$1-$k.log; }
    show /tmp/p-$1-$k.json "$1 process $k:"
    echo "  cache: $(find $d -type f | wc -l) files, $(du -sk $d | cut -f1) KB: $(find $d -type f -printf '%s %P\n' | sort -k2 | head -6 | tr '\n' ';')"
  done
}
probe plain
probe skipcleanup __GL_SHADER_DISK_CACHE_SKIP_CLEANUP=1
# The driver's default location (no overrides at all)
for k in 1 2; do
  timeout 60 /tmp/render scenes/living-room/scene.json -o /tmp/p.png --backend gpu --spp 10 --stats /tmp/p-default-$k.json -q > /dev/null 2>&1
  show /tmp/p-default-$k.json "default env, process $k:"
done
echo "HOME=$HOME; $(find $HOME/.cache -maxdepth 3 2>/dev/null | head -5 | tr '\n' ' ')"
