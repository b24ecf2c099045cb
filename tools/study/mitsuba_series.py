# Mitsuba 3's side of the error-versus-time study (tools/study): shared/peers/mitsuba/series.py's
# protocol, for several samplers in one process, on either of the study's scenes.
#
# usage: python3 mitsuba_series.py SCENE_DIR OUT_DIR --size 500x500 --spp 4,16,64,256,1024 \
#            --samplers multijitter,independent --ref 16384 [--depth 11] [--variant cuda_ad_rgb]
#            [--tungsten PATH]
#
# Per sampler, as series.py does: the scene converted by tungsten.py's scene_dict with that
# sampler, one warm-up render (JIT), then every spp rendered 3 times (seeds 100, 101, 102), the
# fastest time kept and the last image written as NAME-mi-SAMPLER-SPP.exr; the times go to
# NAME-mi-series-SAMPLER.json in series.py's format ({"scene", "size", "sampler", "depth",
# "times": {spp: seconds}}, plus "variant"), which `study mitsuba` reads.
# With --ref N: Mitsuba's own reference, N spp with the independent sampler in chunks of 1024
# (seeds from 10000; cuda_ad_rgb fails above ~10k spp in one call, mitsuba3 #1335), summed by
# Dr.Jit (no numpy needed): NAME-mi-ref-N.exr and NAME-mi-ref.json.
#
# Differences from series.py, both needed for raylume's living room: the constant environment
# written as an `infinite_sphere` primitive with an `emission` (which tungsten.py does not know)
# becomes a Mitsuba `constant` emitter, as tools/agree/mitsuba_ref.py does; and several samplers
# share one import.
import argparse, json, os, sys, time

ap = argparse.ArgumentParser()
ap.add_argument("scene"); ap.add_argument("out")
ap.add_argument("--size", default="500x500"); ap.add_argument("--spp", default="4,16,64,256,1024")
ap.add_argument("--samplers", default="multijitter,independent")
ap.add_argument("--ref", type=int, default=0); ap.add_argument("--ref-chunk", type=int, default=1024)
ap.add_argument("--depth", type=int, default=11); ap.add_argument("--variant", default="cuda_ad_rgb")
ap.add_argument("--repeats", type=int, default=3)
ap.add_argument("--tungsten", default=None)
a = ap.parse_args()

here = os.path.dirname(os.path.abspath(__file__))
conv = a.tungsten
if conv is None:
    for c in (os.path.join(here, "tungsten.py"),
              os.path.join(here, "..", "..", "..", "shared", "peers", "mitsuba", "tungsten.py")):
        if os.path.exists(c):
            conv = c; break
if conv is None or not os.path.exists(conv):
    raise SystemExit("mitsuba_series.py: tungsten.py not found (give --tungsten PATH)")

t0 = time.time()
src = open(conv).read().split("name = os.path.basename")[0]
sys.argv = ["tungsten.py", a.scene, a.out, a.variant, "--size", a.size, "--depth", str(a.depth)]
g = {"__name__": "conv"}
exec(compile(src, conv, "exec"), g)
mi, dr = g["mi"], g["dr"]
d = g["d"]
env = None
prims = []
for p in d["primitives"]:
    if p.get("type") == "infinite_sphere":
        e = p.get("emission")
        if e is None:
            raise SystemExit("mitsuba_series.py: infinite_sphere without a constant `emission` is not handled")
        env = [float(e)] * 3 if isinstance(e, (int, float)) else [float(x) for x in e]
    else:
        prims.append(p)
d["primitives"] = prims
print("mitsuba %s: import %.1f s" % (mi.__version__, time.time() - t0), flush=True)

os.makedirs(a.out, exist_ok=True)
name = os.path.basename(os.path.normpath(a.scene))


def load(sampler):
    sd = g["scene_dict"]()
    sd["sensor"]["sampler"] = {"type": sampler, "sample_count": 1}
    if env is not None:
        sd["sky"] = {"type": "constant", "radiance": {"type": "rgb", "value": env}}
    t = time.time(); scene = mi.load_dict(sd)
    mi.render(scene, spp=1); dr.sync_thread()
    print("mitsuba %s %s: load and warm-up %.1f s" % (name, sampler, time.time() - t), flush=True)
    return scene


for sampler in a.samplers.split(","):
    scene = load(sampler)
    res = {"scene": name, "size": a.size, "sampler": sampler, "depth": a.depth, "variant": a.variant,
           "mitsuba": mi.__version__, "times": {}}
    for spp in [int(x) for x in a.spp.split(",")]:
        best = 1e9
        for rep in range(a.repeats):
            t = time.time(); img = mi.render(scene, spp=spp, seed=100 + rep); dr.sync_thread()
            best = min(best, time.time() - t)
        res["times"][spp] = best
        mi.util.write_bitmap(os.path.join(a.out, "%s-mi-%s-%d.exr" % (name, sampler, spp)), img, write_async=False)
        print("mitsuba %s %s %s spp %d: %.4f s" % (name, a.size, sampler, spp, best), flush=True)
    json.dump(res, open(os.path.join(a.out, "%s-mi-series-%s.json" % (name, sampler)), "w"), indent=1)

if a.ref:
    scene = load("independent")
    t = time.time(); acc = None; n = 0; i = 0
    while n < a.ref:
        k = min(a.ref_chunk, a.ref - n)
        img = mi.render(scene, spp=k, seed=10000 + i) * k
        acc = img if acc is None else acc + img
        n += k; i += 1
        dr.eval(acc)
    acc = acc / n
    dr.eval(acc); dr.sync_thread()
    secs = time.time() - t
    mi.util.write_bitmap(os.path.join(a.out, "%s-mi-ref-%d.exr" % (name, n)), acc, write_async=False)
    json.dump({"scene": name, "size": a.size, "depth": a.depth, "variant": a.variant, "sampler": "independent",
               "spp": n, "chunks": i, "seconds": secs},
              open(os.path.join(a.out, "%s-mi-ref.json" % name), "w"), indent=1)
    print("mitsuba %s ref %d spp in %d chunks: %.1f s" % (name, n, i, secs), flush=True)
