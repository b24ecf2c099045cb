# Mitsuba 3's ray traversal alone, on raylume's own rays: what its BVH (Embree on the CPU's
# llvm variants, OptiX on the GPU's cuda variants) does with the rays `trace_rate` times.
#
# `cargo run --release --example trace_rate -- SCENE --dump DIR` writes the scene's triangles
# (`mesh.ply`, world space) and its two ray sets (`primary.f32`, `diffuse.f32`: eight f32 a
# ray, origin, t_min (0), direction, t_max) with raylume's hit counts (`hits.json`). This loads
# the triangles as one Mitsuba mesh, traces the same rays as closest-hit queries
# (`ray_intersect_preliminary`: the hit's distance and primitive, no surface interaction) and
# as any-hit queries (`ray_test`), best of --repeat after an untimed run (JIT compilation),
# and prints Mrays/s (from the wall clock, and from the kernels' own execution time) and the
# share of rays hit, beside raylume's count (they should agree to a few rays in a million:
# rays grazing an edge).
#
# usage: PYTHONPATH=<mitsuba> python3 mitsuba_trace_rate.py DIR/SCENE [DIR/SCENE ...]
#            [--variant llvm_ad_rgb|cuda_ad_rgb] [--repeat 5] [--json OUT]
import argparse, array, json, os, time

ap = argparse.ArgumentParser()
ap.add_argument("dirs", nargs="+")
ap.add_argument("--variant", default="llvm_ad_rgb")
ap.add_argument("--repeat", type=int, default=5)
ap.add_argument("--json")
a = ap.parse_args()
import mitsuba as mi
mi.set_variant(a.variant)
import drjit as dr
dr.set_flag(dr.JitFlag.KernelHistory, True)

rows = []
print("| scene | triangles | Mitsuba %s | rays | closest Mrays/s (kernel alone) | any Mrays/s (kernel alone) | hit | raylume's hit |" % a.variant)
print("|---|---:|---|---|---:|---:|---:|---:|")
for d in a.dirs:
    name = os.path.basename(os.path.normpath(d))
    t0 = time.perf_counter()
    scene = mi.load_dict({"type": "scene",
                          "mesh": {"type": "ply", "filename": os.path.join(d, "mesh.ply"),
                                   "face_normals": True}})
    load_s = time.perf_counter() - t0
    tris = scene.shapes()[0].face_count()
    ours = json.load(open(os.path.join(d, "hits.json")))
    for kind in ("primary", "diffuse"):
        raw = array.array("f")
        with open(os.path.join(d, kind + ".f32"), "rb") as f:
            raw.frombytes(f.read())
        n = len(raw) // 8
        flat = mi.Float(memoryview(raw))
        index = dr.arange(mi.UInt32, n) * 8
        col = lambda c: dr.gather(mi.Float, flat, index + c)
        ray = mi.Ray3f(mi.Point3f(col(0), col(1), col(2)), mi.Vector3f(col(4), col(5), col(6)))
        ray.maxt = col(7)
        dr.eval(ray)
        dr.sync_thread()

        def timed(query):
            # Best of the runs' wall clock, and of their kernels' own execution time (Dr.Jit's
            # kernel history: the trace without the Python side's graph building and launch,
            # which matter for a millisecond kernel on a GPU).
            best, best_kernel, hit = float("inf"), float("inf"), None
            for rep in range(a.repeat + 1):
                dr.kernel_history()
                t0 = time.perf_counter()
                h = query()
                dr.eval(h)
                dr.sync_thread()
                s = time.perf_counter() - t0
                kernel = sum(k["execution_time"] for k in dr.kernel_history()) / 1000.0
                if rep > 0:
                    best, best_kernel = min(best, s), min(best_kernel, kernel)
                hit = h
            count = dr.count(hit)
            return best, best_kernel, int(count[0] if dr.is_array_v(count) else count)

        tc, kc, hc = timed(lambda: scene.ray_intersect_preliminary(ray, coherent=False).is_valid())
        ta, ka, ha = timed(lambda: scene.ray_test(ray))
        row = {"scene": name, "variant": a.variant, "kind": kind, "rays": n, "triangles": tris,
               "closest_mrays_s": n / tc / 1e6, "any_mrays_s": n / ta / 1e6,
               "closest_kernel_mrays_s": n / kc / 1e6, "any_kernel_mrays_s": n / ka / 1e6,
               "hit": hc, "hit_any": ha, "raylume_hit": ours[kind]["hit"], "load_s": load_s}
        rows.append(row)
        print("| %s | %d | %s | %s (%d) | %.0f (%.0f) | %.0f (%.0f) | %.1f %% | %.1f %% |" % (
            name, tris, a.variant, kind, n, row["closest_mrays_s"], row["closest_kernel_mrays_s"],
            row["any_mrays_s"], row["any_kernel_mrays_s"], 100.0 * hc / n,
            100.0 * ours[kind]["hit"] / n), flush=True)
if a.json:
    json.dump(rows, open(a.json, "w"), indent=1)
