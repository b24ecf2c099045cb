# Mitsuba 3 references for the agreement harness (tools/agree/agree.sh): renders a Tungsten
# scene.json, converted by shared/peers/mitsuba/tungsten.py's scene_dict (imported the way
# series.py does, without running its timing part), at one or more sizes, each as two
# independent halves of SPP/2 samples (two EXRs, disjoint seeds), so that compare can average
# them and measure the reference's noise from their difference.
#
# usage: python3 mitsuba_ref.py SCENE_DIR OUT_DIR --runs 128x128:16384,500x500:8192
#            [--variant cuda_ad_rgb] [--depth 11] [--sampler independent] [--tungsten PATH]
#            [--chunk-samples 256000000]
# writes OUT_DIR/NAME-WxH-mitsuba-a.exr, ...-b.exr and NAME-mitsuba.json (times, spp), where
# NAME is SCENE_DIR's folder name ("mitsuba": --tag; another --tag and --seed make a second,
# independent set, the harness's self-check).
#
# Two adaptations to raylume's copy of the living room (scenes/living-room/README.md):
# - Tungsten's constant environment written as an `infinite_sphere` primitive with an
#   `emission` (tungsten.py knows only the `emissions: envmap` form) becomes a Mitsuba
#   `constant` emitter of that radiance;
# - the leaves, already `lambert` [0.16, 0.3, 0.08] there, need nothing (tungsten.py maps the
#   original `transparency` bsdf to the same diffuse albedo).
# Renders are split in chunks of at most --chunk-samples samples (width x height x spp) and
# 8192 spp: Mitsuba's cuda_ad_rgb fails above ~10k spp in one call (mitsuba3 #1335).
import argparse, json, os, sys, time

ap = argparse.ArgumentParser()
ap.add_argument("scene"); ap.add_argument("out")
ap.add_argument("--runs", required=True, help="WxH:SPP[,WxH:SPP...] (SPP in total, split in two halves)")
ap.add_argument("--variant", default="cuda_ad_rgb"); ap.add_argument("--depth", type=int, default=11)
ap.add_argument("--sampler", default="independent")
ap.add_argument("--tungsten", default=None, help="path of tungsten.py (default: beside this file, "
                "else ../../../shared/peers/mitsuba/tungsten.py from here)")
ap.add_argument("--chunk-samples", type=int, default=256_000_000)
ap.add_argument("--seed", type=int, default=0, help="base seed (halves use disjoint seeds above it)")
ap.add_argument("--tag", default="mitsuba", help="file-name tag: NAME-WxH-TAG-a.exr, NAME-TAG.json")
a = ap.parse_args()

here = os.path.dirname(os.path.abspath(__file__))
conv = a.tungsten
if conv is None:
    for c in (os.path.join(here, "tungsten.py"), os.path.join(here, "..", "..", "..", "shared", "peers", "mitsuba", "tungsten.py")):
        if os.path.exists(c):
            conv = c; break
if conv is None or not os.path.exists(conv):
    raise SystemExit("mitsuba_ref.py: tungsten.py not found (give --tungsten PATH)")
runs = []
for r in a.runs.split(","):
    size, spp = r.split(":")
    w, h = (int(x) for x in size.lower().split("x"))
    spp = int(spp)
    if spp < 2 or spp % 2:
        raise SystemExit("mitsuba_ref.py: spp must be even and >= 2 (two halves), got %d" % spp)
    runs.append((w, h, spp))

# tungsten.py's converter without its main part (the same split as series.py).
src = open(conv).read().split("name = os.path.basename")[0]
w0, h0, _ = runs[0]
sys.argv = ["tungsten.py", a.scene, a.out, a.variant, "--size", "%dx%d" % (w0, h0), "--depth", str(a.depth)]
g = {"__name__": "conv"}
t0 = time.time()
exec(compile(src, conv, "exec"), g)
mi, dr = g["mi"], g["dr"]
d = g["d"]
env = None
prims = []
for p in d["primitives"]:
    if p.get("type") == "infinite_sphere":
        e = p.get("emission")
        if e is None:
            raise SystemExit("mitsuba_ref.py: infinite_sphere without a constant `emission` is not handled")
        env = [float(e)] * 3 if isinstance(e, (int, float)) else [float(x) for x in e]
    else:
        prims.append(p)
d["primitives"] = prims
import_s = time.time() - t0

os.makedirs(a.out, exist_ok=True)
name = os.path.basename(os.path.normpath(a.scene))
res = {"scene": name, "tag": a.tag, "seed": a.seed, "variant": a.variant, "depth": a.depth, "sampler": a.sampler,
       "mitsuba": mi.__version__, "import_s": import_s, "runs": []}
for (w, h, spp) in runs:
    g["W"], g["H"] = w, h
    sd = g["scene_dict"]()
    sd["sensor"]["sampler"] = {"type": a.sampler, "sample_count": 1}
    if env is not None:
        sd["sky"] = {"type": "constant", "radiance": {"type": "rgb", "value": env}}
    t0 = time.time(); scene = mi.load_dict(sd); load_s = time.time() - t0
    t0 = time.time(); mi.render(scene, spp=1, seed=a.seed + 999_999); dr.sync_thread(); warm_s = time.time() - t0
    chunk = max(1, min(8192, a.chunk_samples // (w * h)))
    run = {"size": "%dx%d" % (w, h), "spp": spp, "half_spp": spp // 2, "chunk_spp": chunk,
           "load_s": load_s, "warmup_s": warm_s, "halves": []}
    for half, tag in enumerate("ab"):
        t0 = time.time(); acc = None; n = 0; i = 0
        while n < spp // 2:
            k = min(chunk, spp // 2 - n)
            img = mi.render(scene, spp=k, seed=a.seed + 100_000 * (half + 1) + i) * k
            acc = img if acc is None else acc + img
            n += k; i += 1
        acc = acc / n
        dr.eval(acc); dr.sync_thread()
        secs = time.time() - t0
        path = os.path.join(a.out, "%s-%dx%d-%s-%s.exr" % (name, w, h, a.tag, tag))
        mi.util.write_bitmap(path, acc, write_async=False)
        run["halves"].append({"file": os.path.basename(path), "spp": n, "chunks": i, "seconds": secs})
        print("%s %s %dx%d half %s: %d spp in %d chunks, %.2f s" % (a.tag, name, w, h, tag, n, i, secs), flush=True)
    res["runs"].append(run)
json.dump(res, open(os.path.join(a.out, "%s-%s.json" % (name, a.tag)), "w"), indent=1)
