# The Markdown table of tools/large/large.sh's runs (large.jsonl): per grid, the best of the
# runs of each peer (by raylume's load + BVH, Mitsuba's load), with peak memory.
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
grids = sorted({r["grid"] for r in rows})
print("| triangles | raylume load | raylume BVH (preset) | raylume load + BVH | raylume total | raylume peak | "
      "Mitsuba load + build | Mitsuba total | Mitsuba peak | load + build ratio |")
print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
for g in grids:
    ray = [r for r in rows if r["grid"] == g and r["peer"] == "raylume"]
    mi = [r for r in rows if r["grid"] == g and r["peer"] == "mitsuba"]
    rb = min(ray, key=lambda r: r["seconds"]["load"] + r["seconds"]["bvh"])
    mb = min(mi, key=lambda r: r["load_s"])
    lb = rb["seconds"]["load"] + rb["seconds"]["bvh"]
    print("| {:,} | {:.2f} s | {:.2f} s ({}) | {:.2f} s | {:.2f} s | {:.0f} MB | {:.2f} s | {:.2f} s | {:.0f} MB | {:.2f}x |".format(
        rb["triangles"], rb["seconds"]["load"], rb["seconds"]["bvh"], rb["bvh_preset"], lb,
        rb["seconds"]["total"], max(r["peak_kb"] for r in ray) / 1024, mb["load_s"], mb["total_s"],
        max(r["peak_kb"] for r in mi) / 1024, lb / mb["load_s"]))
print()
print("(best of %d runs each; ratio < 1: raylume faster)" % max(len([r for r in rows if r["grid"] == g and r["peer"] == "raylume"]) for g in grids))
