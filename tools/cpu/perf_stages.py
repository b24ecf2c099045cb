#!/usr/bin/env python3
"""Where a CPU render's time goes, by the inlined function each sample's instruction belongs to.

The CPU path is one function per instruction-set level (`cpu::isa`'s `call_v3`/`call_v4`
copies, everything inlined), so `perf report --sort sym` puts all of it in one line. This
attributes each sample to the innermost inlined frame (`addr2line -i`) whose name holds one of
KEYS, the first key in the order given wins (default: the walks, the Sobol' draw, the
packets' shading), and prints the split and the hottest source lines.

  CARGO_TARGET_DIR=target/cpu-prof CARGO_PROFILE_RELEASE_DEBUG=line-tables-only \
      cargo build --release --example render
  perf record -F 2000 -e cpu-clock -o /tmp/perf.data \
      target/cpu-prof/release/examples/render SCENE --backend cpu --size 400x400 --spp 16 -q -o /tmp/o.png
  tools/cpu/perf_stages.py /tmp/perf.data target/cpu-prof/release/examples/render [KEYS...]

A timer-sampled profile (the VMs give no hardware counters) charges a stall to the
instruction waiting to retire: work whose latency the out-of-order core hides behind a walk
(the Sobol' draw: 14 % of the Cornell box's samples, yet a second draw a segment costs no
time) still collects samples. Confirm a share by changing the code before acting on it.
TOP (environment, default 40): source lines listed.
"""
import subprocess, sys, collections, re, os
data, binary = sys.argv[1], sys.argv[2]
keys = sys.argv[3:] or ['trace_closest', 'trace_any', 'draw_avx2', 'segment_rands', 'camera_path_at',
                       'surface_at', 'shade_hit', 'light_query', 'shade<', 'trace_ray_at', 'trace_chunk']
mm = subprocess.run(['perf', 'script', '-i', data, '--show-mmap-events'], capture_output=True, text=True).stdout
base = None
for line in mm.split('\n'):
    if 'MMAP' in line and line.rstrip().endswith(os.path.basename(binary)) and 'r-xp' in line:
        m = re.search(r'\[(0x[0-9a-f]+)\((0x[0-9a-f]+)\) @ (0x[0-9a-f]+)', line)
        base = (int(m.group(1), 16), int(m.group(3), 16)); break
seg = subprocess.run(['readelf', '-lW', binary], capture_output=True, text=True).stdout
delta = 0
for line in seg.split('\n'):
    p = line.split()
    if p and p[0] == 'LOAD' and 'E' in p[-2:-1] + [p[-2]]:
        delta = int(p[2], 16) - int(p[1], 16)
out = subprocess.run(['perf', 'script', '-i', data, '-F', 'ip,dso'], capture_output=True, text=True).stdout
ips = collections.Counter(); total = 0
for line in out.split('\n'):
    parts = line.split()
    if len(parts) >= 2:
        total += 1
        if binary in parts[1]:
            ip = int(parts[0], 16) - base[0] + base[1] + delta
            ips[ip] += 1
addrs = sorted(ips)
r = subprocess.run(['addr2line', '-a', '-f', '-i', '-C', '-e', binary] + [hex(a) for a in addrs], capture_output=True, text=True).stdout.split('\n')
chains = {}; cur = None
i = 0
while i < len(r):
    l = r[i]
    if l.startswith('0x'):
        cur = int(l, 16); chains[cur] = []; i += 1; continue
    if i + 1 < len(r) and cur is not None:
        chains[cur].append((l, r[i + 1])); i += 2
    else:
        i += 1
by = collections.Counter(); lines = collections.Counter()
for a, n in ips.items():
    ch = chains.get(a, [])
    cat = 'other'
    for fn, loc in ch:
        hit = [k for k in keys if k in fn]
        if hit:
            cat = hit[0]; break
    by[cat] += n
    # The innermost frame in the project's own sources (an intrinsic's or glam's line says
    # less than the line of ours that called it).
    own = [(fn, loc) for fn, loc in ch if '/crates/' in loc or loc.startswith('crates/')]
    fn, loc = (own or ch or [('?', '?')])[0]
    lines[(cat, loc.split('/')[-1].split(' ')[0], fn.split('(')[0][-70:])] += n
print(f'{total} samples, {sum(ips.values())} in the binary')
for k, n in by.most_common():
    print(f'{100*n/total:6.2f}% {k}')
print()
for (c, l, f), n in lines.most_common(int(os.environ.get('TOP', '40'))):
    print(f'{100*n/total:6.2f}% {c:16} {l:28} {f}')
