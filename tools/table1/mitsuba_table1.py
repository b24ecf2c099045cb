# Mitsuba 3's side of the GPU-speed comparison (issue 13; tools/table1/table1.sh runs it on the
# device beside raylume's bench): one Tungsten scene (raylume's copy of Bitterli's, as the
# study reads it) through shared/peers/mitsuba/tungsten.py's conversion, with a constant
# environment `infinite_sphere` as a Mitsuba `constant` emitter (tools/study/mitsuba_series.py
# does the same), Mitsuba's `path` integrator (NEE, MIS, Russian roulette from depth 5), box
# filter, independent sampler.
#
# usage: python3 mitsuba_table1.py SCENE_DIR OUT_DIR --tungsten PATH [--size 1000x1000]
#            [--spp 1,10,100] [--depth 11] [--variant cuda_ad_rgb] [--first-spp 10]
#
# Measures, in this order, and writes NAME-mi-table1.json:
# - import_s: importing mitsuba and setting the variant;
# - load_s: mi.load_dict of the converted scene (parsing the meshes, building its BVH);
# - first_render_s: the first render at --first-spp, synchronised (JIT compilation included:
#   cold when Dr.Jit's kernel cache is empty, as on a fresh machine), and first_write_s for
#   writing it as PNG: load_s + first_render_s + first_write_s is the "file to image" time;
# - spp{N}_s: the best of 3 renders at each --spp (seeds 1..3), after the first.
import argparse, json, os, sys, time

T0 = time.time()
ap = argparse.ArgumentParser()
ap.add_argument("scene"); ap.add_argument("out")
ap.add_argument("--tungsten", required=True)
ap.add_argument("--size", default="1000x1000"); ap.add_argument("--spp", default="1,10,100")
ap.add_argument("--depth", type=int, default=11); ap.add_argument("--variant", default="cuda_ad_rgb")
ap.add_argument("--first-spp", type=int, default=10)
a = ap.parse_args()

src = open(a.tungsten).read().split("name = os.path.basename")[0]
sys.argv = ["tungsten.py", a.scene, a.out, a.variant, "--size", a.size, "--depth", str(a.depth)]
g = {"__name__": "conv"}
exec(compile(src, a.tungsten, "exec"), g)
mi, dr = g["mi"], g["dr"]
res = {"scene": os.path.basename(os.path.normpath(a.scene)), "size": a.size, "depth": a.depth,
       "variant": a.variant, "mitsuba": mi.__version__, "import_s": time.time() - T0}
d = g["d"]
env = None
prims = []
for p in d["primitives"]:
    if p.get("type") == "infinite_sphere":
        e = p.get("emission")
        if e is None:
            raise SystemExit("mitsuba_table1.py: infinite_sphere without a constant `emission` is not handled")
        env = [float(e)] * 3 if isinstance(e, (int, float)) else [float(x) for x in e]
    else:
        prims.append(p)
d["primitives"] = prims
sd = g["scene_dict"]()
if env is not None:
    sd["sky"] = {"type": "constant", "radiance": {"type": "rgb", "value": env}}
os.makedirs(a.out, exist_ok=True)
name = res["scene"]

t = time.time(); scene = mi.load_dict(sd); res["load_s"] = time.time() - t
t = time.time(); img = mi.render(scene, spp=a.first_spp, seed=0); dr.sync_thread()
res["first_render_s"] = time.time() - t
res["first_spp"] = a.first_spp
t = time.time()
mi.util.write_bitmap(os.path.join(a.out, "%s-mi-first.png" % name), img, write_async=False)
res["first_write_s"] = time.time() - t
print("mitsuba %s: import %.2f s, load %.2f s, first render (%d spp, JIT included) %.2f s, png %.3f s"
      % (name, res["import_s"], res["load_s"], a.first_spp, res["first_render_s"], res["first_write_s"]), flush=True)
for spp in [int(x) for x in a.spp.split(",")]:
    best = 1e9
    for rep in range(3):
        t = time.time(); img = mi.render(scene, spp=spp, seed=rep + 1); dr.sync_thread()
        best = min(best, time.time() - t)
    res["spp%d_s" % spp] = best
    print("mitsuba %s %s depth %d spp %d: %.4f s" % (name, a.size, a.depth, spp, best), flush=True)
json.dump(res, open(os.path.join(a.out, "%s-mi-table1.json" % name), "w"), indent=1)
