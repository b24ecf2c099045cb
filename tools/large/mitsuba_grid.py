# Mitsuba 3's side of issue 19's large-scene comparison (tools/large/large.sh runs it beside
# raylume's `render`): the scene tools/large/large.sh writes as TOML for raylume (one OBJ mesh,
# grey diffuse 0.8, a constant environment of 1.0, a perspective camera with a 40-degree
# vertical fov looking down at the unit-square grid), built as a Mitsuba dict, rendered by
# Mitsuba's `path` integrator (max_depth = bounces + 1), independent sampler, box filter.
#
# usage: python3 mitsuba_grid.py OBJ OUT_JSON [--variant llvm_ad_rgb] [--size 128x128]
#            [--spp 4] [--bounces 10] [--png OUT.png]
#
# Writes (JSON): import_s (import mitsuba + set the variant), load_s (mi.load_dict: the OBJ
# parsed, the scene's BVH built: Embree on llvm, OptiX on cuda), render_s (the first render,
# synchronised, JIT compilation included), write_s, and total_s = load_s + render_s + write_s:
# "from the file to the image", as raylume's `total`.
import argparse, json, os, sys, time

T0 = time.time()
ap = argparse.ArgumentParser()
ap.add_argument("obj"); ap.add_argument("out")
ap.add_argument("--variant", default="llvm_ad_rgb")
ap.add_argument("--size", default="128x128"); ap.add_argument("--spp", type=int, default=4)
ap.add_argument("--bounces", type=int, default=10); ap.add_argument("--png")
a = ap.parse_args()
import drjit as dr
import mitsuba as mi
mi.set_variant(a.variant)
res = {"obj": os.path.basename(a.obj), "variant": a.variant, "mitsuba": mi.__version__,
       "size": a.size, "spp": a.spp, "bounces": a.bounces, "import_s": time.time() - T0}
w, h = (int(x) for x in a.size.split("x"))
scene = {
    "type": "scene",
    "integrator": {"type": "path", "max_depth": a.bounces + 1},
    "sensor": {
        "type": "perspective", "fov": 40.0, "fov_axis": "y",
        "to_world": mi.ScalarTransform4f().look_at(origin=[0.5, 0.6, 1.6], target=[0.5, 0.0, 0.5], up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}},
        "sampler": {"type": "independent", "sample_count": a.spp},
    },
    "sky": {"type": "constant", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}},
    "grid": {"type": "obj", "filename": os.path.abspath(a.obj), "face_normals": True,
             "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.8, 0.8, 0.8]}}},
}
t = time.time(); s = mi.load_dict(scene); res["load_s"] = time.time() - t
t = time.time(); img = mi.render(s, spp=a.spp, seed=0); dr.sync_thread(); res["render_s"] = time.time() - t
t = time.time()
if a.png:
    mi.util.write_bitmap(a.png, img, write_async=False)
res["write_s"] = time.time() - t
res["total_s"] = res["load_s"] + res["render_s"] + res["write_s"]
json.dump(res, open(a.out, "w"), indent=1)
print(json.dumps(res))
