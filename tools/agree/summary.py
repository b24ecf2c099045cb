# The agreement harness's table (tools/agree/agree.sh): reads the work folder (compare's JSON
# per case, render's --stats, mitsuba_ref.py's JSON) and prints Markdown, one row per scene
# and size, with the verdict of issue 11's criterion:
#   converged: the noise alone (null image of compare) has p95 <= tolerance / 2 and the
#              standard error of the mean ratio is <= 0.2 %;
#   mean:      |raylume / Mitsuba image mean - 1| <= 1 % (over all channels);
#   blocks:    >= 95 % of 8x8 blocks within the tolerance (3 %).
# PASS: converged and both criteria met.
# FAIL: a criterion fails by more than noise explains: the mean ratio is off by more than
#       1 % + 3 sigma, or more than 5 % of the blocks are outside the tolerance by more than
#       3 of their standard errors (from the halves' pixel variances).
# NOISY: neither: the noise is too large to judge (raise the spp; the numbers are still shown).
# Standard library only (the GPU machine's Python has no numpy).
# usage: python3 summary.py WORK_DIR [--tolerance 0.03] [--json OUT.json]
import argparse, glob, json, os

ap = argparse.ArgumentParser()
ap.add_argument("work"); ap.add_argument("--tolerance", type=float, default=0.03)
ap.add_argument("--json", default=None)
a = ap.parse_args()
MEAN_TOL, BLOCK_FRACTION, SIGMA_MAX = 0.01, 0.95, 0.002


def load(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


mitsuba, selfcheck = {}, {}
for p in glob.glob(os.path.join(a.work, "*-mitsuba*.json")):
    m = load(p)
    if m and "runs" in m:
        for r in m["runs"]:
            (selfcheck if m.get("tag") == "mitsuba-self" else mitsuba)[(m["scene"], r["size"])] = (m, r)

rows = []
for p in sorted(glob.glob(os.path.join(a.work, "*-compare.json"))):
    case = os.path.basename(p)[: -len("-compare.json")]
    scene, size = case.rsplit("-", 1)
    c = load(p)
    if c is None:
        continue
    stats = [load(os.path.join(a.work, "%s-raylume-%s.stats.json" % (case, h))) for h in "ab"]
    m, mr = mitsuba.get((scene, size), (None, None))
    sm, sr = selfcheck.get((scene, size), (None, None))
    b = c.get("blocks") or {}
    noise = b.get("noise") or {}
    sig = (c.get("mean_ratio_noise") or {}).get("all")
    ratio = c["mean_ratio"]
    worst = (b.get("worst") or [None])[0]
    conv = noise.get("p95") is not None and noise["p95"] <= a.tolerance / 2 and sig is not None and sig <= SIGMA_MAX
    mean_ok = abs(ratio["all"] - 1) <= MEAN_TOL
    blocks_ok = b.get("within", 0) >= BLOCK_FRACTION
    mean_bad = not mean_ok and sig is not None and abs(ratio["all"] - 1) > MEAN_TOL + 3 * sig
    nw = noise.get("within")
    beyond, n = b.get("outside_beyond_noise"), b.get("count") or 1
    if beyond is not None:   # the per-block standard errors decide
        blocks_bad = not blocks_ok and beyond > 1 - BLOCK_FRACTION
    else:                    # only the null image: far more misses than it has
        blocks_bad = not blocks_ok and nw is not None and b.get("within", 0) < nw - max(0.05, 3 * (nw * (1 - nw) / n) ** 0.5)
    verdict = "PASS" if conv and mean_ok and blocks_ok else "FAIL" if mean_bad or blocks_bad else "NOISY"
    rows.append({
        "scene": scene, "size": size,
        "test": "raylume" if sr is None else "Mitsuba self-check (seed %d)" % sm["seed"],
        "raylume_spp": sr["spp"] if sr else sum(s["spp"] for s in stats if s),
        "mitsuba_spp": mr["spp"] if mr else None,
        "raylume": {"backend": stats[0]["backend"] if stats[0] else None,
                    "adapter": stats[0]["adapter"] if stats[0] else "Mitsuba %s (self-check)" % sm["variant"] if sm else None,
                    "estimator": stats[0]["estimator"] if stats[0] else None,
                    "seconds": sum(h["seconds"] for h in sr["halves"]) if sr else sum(s["seconds"]["total"] for s in stats if s)},
        "mitsuba": {"variant": m["variant"] if m else None,
                    "seconds": sum(h["seconds"] for h in mr["halves"]) if mr else None},
        "mean_ratio": ratio, "mean_ratio_sigma": sig,
        "blocks_within": b.get("within"), "blocks_p95": b.get("p95"), "blocks_count": b.get("count"),
        "blocks_floored": b.get("floored"),
        "noise_within": noise.get("within"), "noise_p95": noise.get("p95"),
        "blocks_outside_beyond_noise": b.get("outside_beyond_noise"), "block_sigma_p95": b.get("sigma_p95"),
        "worst_block": worst, "converged": conv, "mean_ok": mean_ok, "blocks_ok": blocks_ok,
        "mean_fails_beyond_noise": mean_bad, "blocks_fail_beyond_noise": blocks_bad,
        "verdict": verdict, "rmse": c["rmse"], "relative_mse": c["relative_mse"], "ssim": c["ssim"],
    })


def pct(v, d=1):
    return "-" if v is None else "%.*f %%" % (d, 100 * v)


if any(r["test"] != "raylume" for r in rows):
    print("**Self-check: the test is a second, independent Mitsuba at the raylume column's spp; it must PASS.**\n")
print("| scene | size | raylume spp | Mitsuba spp | mean ratio (R / G / B) | blocks within %s | block p95 | noise: within, p95 | out by > 3 sigma | worst block | converged | verdict |"
      % pct(a.tolerance, 0))
print("|---|---|---:|---:|---|---:|---:|---|---:|---|---|---|")
for r in rows:
    mr = r["mean_ratio"]
    sig = "" if r["mean_ratio_sigma"] is None else " ± %.4f" % r["mean_ratio_sigma"]
    w = r["worst_block"]
    ws = "-" if w is None else "%+.1f %%%s at x %d..%d, y %d..%d" % (
        100 * w["error"], "" if w.get("sigma") is None else " ± %.1f %%" % (100 * w["sigma"]), w["x0"], w["x1"], w["y0"], w["y1"])
    print("| %s | %s | %s | %s | %.4f%s (%.3f / %.3f / %.3f) | %s | %s | %s, %s | %s | %s | %s | **%s** |" % (
        r["scene"], r["size"], r["raylume_spp"], r["mitsuba_spp"], mr["all"], sig, mr["r"], mr["g"], mr["b"],
        pct(r["blocks_within"]), pct(r["blocks_p95"], 2), pct(r["noise_within"]), pct(r["noise_p95"], 2),
        pct(r["blocks_outside_beyond_noise"]), ws,
        "yes" if r["converged"] else "no", r["verdict"]))
print()
print("PASS: converged (noise p95 <= %s, mean-ratio sigma <= %.1f %%), |mean ratio - 1| <= %.0f %%, "
      ">= %.0f %% of 8x8 blocks within %s. FAIL: a criterion fails beyond noise. NOISY: cannot tell yet. "
      "Times (s, both halves): %s." % (
          pct(a.tolerance / 2), 100 * SIGMA_MAX, 100 * MEAN_TOL, 100 * BLOCK_FRACTION, pct(a.tolerance, 0),
          "; ".join("%s %s raylume %.1f (%s), Mitsuba %s" % (
              r["scene"], r["size"], r["raylume"]["seconds"], r["raylume"]["adapter"],
              "-" if r["mitsuba"]["seconds"] is None else "%.1f" % r["mitsuba"]["seconds"]) for r in rows)))
if a.json:
    with open(a.json, "w") as f:
        json.dump(rows, f, indent=1)
