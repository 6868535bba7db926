"""Time against error for kdtrace (CPU and GPU), Cycles and Mitsuba 3 on the same scenes.

For each scene: a converged reference from Mitsuba (two half references with different seeds,
averaged; their difference estimates the reference's own error, the floor under every curve),
then every renderer at an increasing sample count, up to the first rung of 256 spp or more under
relMSE 1e-3 (or the scene's cap). Each image is scored against the reference
with `kdtrace compare --json` (RMSE, relMSE, MAE, ꟻLIP). Writes bench/results/time_vs_error.csv,
a log-log plot of relMSE against time (bench/results/time_vs_error.png), and a summary
(bench/results/summary.json and a Markdown table on stdout): per renderer and scene the fitted
error exponent (slope of log relMSE against log time; -1 for an unbiased Monte Carlo estimator)
and the time to relMSE 1e-3, interpolated log-log between the two ladder points around it, or
extrapolated along the fit when the ladder does not reach it (marked).

Time is what each renderer spends after its scene file is parsed, including building its
acceleration structure: kdtrace `build_s + prepare_s + render_s`, Mitsuba `load_dict + render`, Cycles the
render operator (scene sync, BVH, render, EXR write). Process start-up is left out of all.

Run through bench/peers.sh (it sets up the venv and DRJIT_LIBLLVM_PATH).
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PY = sys.executable
KDTRACE = os.path.join(ROOT, "target", "release", "kdtrace")

SCENES = {
    "cornell-box": {
        "obj": os.path.join(ROOT, "scenes", "cornell-box.obj"),
        # Cornell's published camera in our frame (scenes/cornell-box.md).
        "camera": ["--eye=0.278,0.273,0.8", "--target=0.278,0.273,0", "--up=0,1,0", "--fov=39.3076"],
    },
    "CornellBox-Sphere": {
        "obj": os.path.join(ROOT, "..", "shared", "scenes", "CornellBox-Sphere", "CornellBox-Sphere.obj"),
        # kdtrace's default framing of this scene's bounding box, written out (`--eye=` keeps
        # argparse from reading -0.01 as an option).
        "camera": ["--eye=-0.01,0.795,3.817", "--target=-0.01,0.795,0.493", "--up=0,1,0", "--fov=39.3076"],
    },
    # CornellBox-Original (Morgan McGuire's archive) from a camera of our own choosing, off the
    # axis the scene's authors framed.
    "CornellBox-Original": {
        "obj": os.path.join(ROOT, "tests", "data", "meshes", "CornellBox-Original", "CornellBox-Original.obj"),
        "camera": ["--eye=0.35,1.1,3.5", "--target=-0.1,0.9,0", "--up=0,1,0", "--fov=40"],
    },
    # A room lit by a lamp hidden behind a partition (scenes/uneven-noise.md), its own camera.
    "uneven-noise": {
        "obj": os.path.join(ROOT, "scenes", "uneven-noise.obj"),
        "camera": ["--eye=0.4,1.0,3.9", "--target=2.6,1.0,0.5", "--up=0,1,0", "--fov=70"],
    },
    # Composed by bench/peers/make_scenes.py into OUT/scenes at the start of a run.
    "buddha-box": {
        "generated": "buddha-box.obj",
        "camera": ["--eye=0.42,0.33,0.75", "--target=0.25,0.2,-0.3", "--up=0,1,0", "--fov=40"],
        "max_spp": 256,
    },
    "bunny-box": {
        "generated": "bunny-box.obj",
        "camera": ["--eye=0.278,0.273,0.8", "--target=0.278,0.273,0", "--up=0,1,0", "--fov=39.3076"],
        "max_spp": 256,
    },
    "sponza-sky": {
        "generated": "sponza-sky.obj",
        "camera": ["--eye=-11,3,0", "--target=11,5,0", "--up=0,1,0", "--fov=55"],
        # Long paths in a closed building: 4-5x the Cornell box's time per sample. Mitsuba
        # needs about 2,000 spp for relMSE 1e-3 here, so its ladder goes to 4096 and the time is
        # interpolated, not extrapolated; a 4096-spp reference's own relMSE (~4e-4) would be
        # most of the target, so the reference takes 16384.
        "max_spp": 4096,
        "ref_spp": 16384,
    },
}

# A ladder stops at the first rung of 256 spp or more whose relMSE is under TARGET: the rungs
# after it add time without moving the time to the target (and 256 keeps a per-sample figure
# at a count every renderer reaches).
TARGET = 1e-3
STOP_FROM_SPP = 256

LADDERS = {
    "kdtrace-cpu": [4, 16, 64, 256, 1024, 4096],
    # The k-d tree instead of the CPU path's wide BVH (`--traversal full`): what the BVH alone buys.
    "kdtrace-cpu-kd": [4, 16, 64, 256, 1024],
    # The generic integrator (`--specialize off`): what specialisation alone buys.
    "kdtrace-cpu-generic": [4, 16, 64, 256, 1024],
    # Light subpaths connected to the eye vertices, and path tracing alone (`--connect on|off`):
    # what the connections alone buy.
    "kdtrace-cpu-connect": [4, 16, 64, 256, 1024, 4096],
    "kdtrace-cpu-pathtrace": [4, 16, 64, 256, 1024, 4096],
    # The connections with each sample's own light subpath instead of the CPU's pool
    # (`--light-pool off`, the GPU's estimator): what the pool alone buys.
    "kdtrace-cpu-ownlight": [4, 16, 64, 256, 1024, 4096],
    # Adaptive sampling: the rungs are thresholds (`--adaptive`), each pixel up to 8192 spp.
    "kdtrace-cpu-adaptive": [0.2, 0.1, 0.05, 0.03, 0.02],
    "kdtrace-cpu-asyougo": [0.2, 0.1, 0.05, 0.03, 0.02],
    # The same CPU path with independent uniforms instead of Sobol points (`--sampler`).
    "kdtrace-cpu-independent": [4, 16, 64, 256, 1024],
    "kdtrace-gpu": [4, 16, 64],
    "cycles": [4, 16, 64, 256],
    "mitsuba": [4, 16, 64, 256, 1024, 4096],
    # Mitsuba with its low-discrepancy sampler (padded (0,2)-sequences) instead of its default.
    "mitsuba-ldsampler": [4, 16, 64, 256, 1024, 4096],
}


# The most samples one pixel may take under adaptive sampling (`--spp` with `--adaptive`).
ADAPTIVE_MAX_SPP = 8192


def last_json(stdout):
    for line in reversed(stdout.strip().splitlines()):
        # Drop what precedes the object (a log line's colour codes).
        line = line.strip()
        if "{" in line and line.endswith("}"):
            return json.loads(line[line.index("{"):])
    raise RuntimeError("no JSON line in output:\n" + stdout[-2000:])


def run(cmd):
    t = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stdout[-3000:]}\n{p.stderr[-3000:]}")
    return last_json(p.stdout), wall


def render(renderer, scene, spp, seed, out, a):
    common = ["--spp", str(spp), "--width", str(a.size), "--height", str(a.size), "--bounces", str(a.bounces), "--seed", str(seed)] + SCENES[scene]["camera"]
    obj = SCENES[scene]["obj"]
    if renderer.startswith("kdtrace"):
        dev = renderer.split("-")[1]
        extra = {
            "-independent": ["--sampler", "independent"],
            "-generic": ["--specialize", "off"],
            "-kd": ["--traversal", "full"],
            "-connect": ["--connect", "on"],
            "-pathtrace": ["--connect", "off"],
            "-ownlight": ["--light-pool", "off"],
            "-adaptive": ["--adaptive", str(spp), "--adaptive-mode", "pilot"],
            "-asyougo": ["--adaptive", str(spp), "--adaptive-mode", "as-you-go"],
        }
        extra = next((v for k, v in extra.items() if renderer.endswith(k)), [])
        if "--adaptive" in extra:
            # Slow scenes cap their fixed ladders (`max_spp`); adaptive pixels may go 4x further.
            common[1] = str(min(ADAPTIVE_MAX_SPP, 4 * SCENES[scene].get("max_spp", ADAPTIVE_MAX_SPP)))
        j, wall = run([KDTRACE, "render", obj, "--out", out, "--device", dev, "--json"] + extra + common)
        return j["build_s"] + j.get("prepare_s", 0.0) + j["render_s"], wall, j
    base, _, variant = renderer.partition("-")
    script = os.path.join(ROOT, "bench", "peers", f"render_{base}.py")
    extra = ["--sampler", variant] if variant else []
    j, wall = run([PY, script, obj, "--out", out, "--json"] + extra + common)
    return j.get("load_s", 0.0) * (base == "mitsuba") + j["render_s"], wall, j


def compare(ref, test):
    j, _ = run([KDTRACE, "compare", ref, test, "--json"])
    return j


def fit_slope(ts, es):
    xs, ys = [math.log(t) for t in ts], [math.log(e) for e in es]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx
    return slope, my - slope * mx


def time_to(target, ts, es):
    pts = sorted(zip(ts, es))
    for (t0, e0), (t1, e1) in zip(pts, pts[1:]):
        if (e0 - target) * (e1 - target) <= 0 and e0 != e1:
            f = (math.log(target) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + f * (math.log(t1) - math.log(t0))), "interpolated"
    slope, icpt = fit_slope(ts, es)
    return math.exp((math.log(target) - icpt) / slope), "extrapolated"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--bounces", type=int, default=6)
    ap.add_argument("--ref-spp", type=int, help="Mitsuba reference spp (two halves); each scene's own (4096 unless it says) if not given")
    ap.add_argument("--reuse-reference", action="store_true", help="keep reference halves already rendered in --out (same spp and size)")
    ap.add_argument("--scenes", default="cornell-box,CornellBox-Sphere", help=f"comma-separated, of: {', '.join(SCENES)}")
    ap.add_argument("--renderers", default=",".join(LADDERS))
    ap.add_argument("--max-spp", type=int, help="the largest fixed-ladder rung for every scene, in place of the slow scenes' own caps")
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    img = os.path.join(a.out, "images")
    os.makedirs(img, exist_ok=True)
    rows, refs = [], {}
    t_all = time.perf_counter()
    generated = os.path.join(a.out, "scenes")
    run([PY, os.path.join(ROOT, "bench", "peers", "make_scenes.py"), generated])
    for spec in SCENES.values():
        if "generated" in spec:
            spec["obj"] = os.path.join(generated, spec["generated"])
    for scene in a.scenes.split(","):
        halves = []
        t_ref = time.perf_counter()
        ref_spp = a.ref_spp or SCENES[scene].get("ref_spp", 4096)
        for h, seed in enumerate([7, 8]):
            out = os.path.join(img, f"{scene}-ref{ref_spp}-{a.size}-half{h}.exr")
            if not (a.reuse_reference and os.path.exists(out)):
                render("mitsuba", scene, ref_spp // 2, seed, out, a)
            halves.append(out)
        ref = os.path.join(img, f"{scene}-ref{ref_spp}-{a.size}.exr")
        run([PY, "-c", "import sys, numpy as np, mitsuba as mi; mi.set_variant('scalar_rgb');"
             "a, b = (np.asarray(mi.Bitmap(p), dtype=np.float64) for p in sys.argv[1:3]);"
             "mi.util.write_bitmap(sys.argv[3], mi.Bitmap(((a + b) / 2).astype(np.float32)), write_async=False); print('{}')",
             halves[0], halves[1], ref])
        ref_s = time.perf_counter() - t_ref
        # Two independent halves differ by twice the variance of one half, which is twice that of
        # the full reference: relMSE(half0, half1) / 4 estimates the reference's own relMSE.
        half_diff = compare(halves[0], halves[1])
        refs[scene] = {"spp": ref_spp, "seconds": ref_s, "relmse_floor": half_diff["relmse"] / 4, "rmse_floor": half_diff["rmse"] / 2}
        print(f"{scene}: reference Mitsuba {ref_spp} spp in {ref_s:.1f} s; reference relMSE ~ {refs[scene]['relmse_floor']:.2e}", flush=True)
        for renderer in a.renderers.split(","):
            cap = a.max_spp or SCENES[scene].get("max_spp")
            for spp in [n for n in LADDERS[renderer] if cap is None or n <= cap]:
                out = os.path.join(img, f"{scene}-{renderer}-{spp}.exr")
                t, wall, j = render(renderer, scene, spp, 0, out, a)
                e = compare(ref, out)
                row = {"scene": scene, "renderer": renderer, "spp": spp, "spp_mean": j.get("spp_mean", spp), "time_s": t, "wall_s": wall,
                       "rmse": e["rmse"], "relmse": e["relmse"], "mae": e["mae"], "flip": e["flip"], "mean_ratio": e["mean_ratio"],
                       "nan": e["test_nonfinite"]["nan"], "inf": e["test_nonfinite"]["inf"]}
                rows.append(row)
                print(json.dumps(row), flush=True)
                if isinstance(spp, int) and spp >= STOP_FROM_SPP and e["relmse"] < TARGET:
                    break
    with open(os.path.join(a.out, "time_vs_error.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)

    summary = {"references": refs, "fits": []}
    for scene in a.scenes.split(","):
        for renderer in a.renderers.split(","):
            rs = [r for r in rows if r["scene"] == scene and r["renderer"] == renderer]
            ts, es = [r["time_s"] for r in rs], [r["relmse"] for r in rs]
            slope, _ = fit_slope(ts, es)
            t1e3, how = time_to(TARGET, ts, es)
            w1e3, whow = time_to(TARGET, [r["wall_s"] for r in rs], es)
            # The reference's own error adds to every measured relMSE (independent errors add):
            # net of it, the time to relMSE 1e-3 against the converged image, from the rungs
            # whose measured error is at least twice the floor.
            floor = refs[scene]["relmse_floor"]
            net = [(t, e - floor) for t, e in zip(ts, es) if e >= 2 * floor]
            n1e3, nhow = time_to(TARGET, [t for t, _ in net], [e for _, e in net]) if len(net) >= 2 else (None, "too few rungs")
            # Seconds per sample per pixel at the largest fixed-spp rung both kdtrace-cpu and
            # Mitsuba rendered (adaptive rungs are thresholds: no per-sample figure).
            per_sample = None
            if not renderer.endswith(("-adaptive", "-asyougo")):
                common = [r for r in rs if r["spp"] in (64, 256)]
                if common:
                    r = max(common, key=lambda r: r["spp"])
                    per_sample = {"spp": r["spp"], "time_s": r["time_s"], "wall_s": r["wall_s"]}
            summary["fits"].append({"scene": scene, "renderer": renderer, "slope": slope, "time_to_relmse_1e-3_s": t1e3, "how": how,
                                    "wall_to_relmse_1e-3_s": w1e3, "wall_how": whow,
                                    "net_of_reference_to_relmse_1e-3_s": n1e3, "net_how": nhow, "per_sample": per_sample})
    summary["total_s"] = time.perf_counter() - t_all
    with open(os.path.join(a.out, "summary.json"), "w") as f:
        json.dump(summary, f, indent=1)

    print("\n| scene | renderer | spp | time s | RMSE | relMSE | FLIP | mean ratio |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['scene']} | {r['renderer']} | {r['spp']} | {r['time_s']:.2f} | {r['rmse']:.4f} | {r['relmse']:.2e} | {r['flip']:.4f} | {r['mean_ratio']:.4f} |")
    print("\n| scene | renderer | slope of log relMSE vs log time | time to relMSE 1e-3 (s) |")
    print("|---|---|---|---|")
    for fit in summary["fits"]:
        print(f"| {fit['scene']} | {fit['renderer']} | {fit['slope']:.3f} | {fit['time_to_relmse_1e-3_s']:.1f} ({fit['how']}) |")
    print("\n| scene | renderer | time to relMSE 1e-3 vs Mitsuba (after parsing) | whole process | net of the reference's error |")
    print("|---|---|---|---|---|")
    for fit in summary["fits"]:
        m = next((f for f in summary["fits"] if f["scene"] == fit["scene"] and f["renderer"] == "mitsuba"), None)
        if m and fit["renderer"].startswith("kdtrace"):
            n, mn = fit["net_of_reference_to_relmse_1e-3_s"], m["net_of_reference_to_relmse_1e-3_s"]
            net = f"{n / mn:.2f}x" if n and mn else "-"
            print(f"| {fit['scene']} | {fit['renderer']} | {fit['time_to_relmse_1e-3_s'] / m['time_to_relmse_1e-3_s']:.2f}x "
                  f"| {fit['wall_to_relmse_1e-3_s'] / m['wall_to_relmse_1e-3_s']:.2f}x | {net} |")
    print(f"\ntotal {summary['total_s']:.0f} s")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    scenes = a.scenes.split(",")
    fig, axes = plt.subplots(1, len(scenes), figsize=(6 * len(scenes), 4.8), squeeze=False)
    for ax, scene in zip(axes[0], scenes):
        for renderer in a.renderers.split(","):
            rs = [r for r in rows if r["scene"] == scene and r["renderer"] == renderer]
            ax.loglog([r["time_s"] for r in rs], [r["relmse"] for r in rs], "o-", label=renderer)
        ax.axhline(1e-3, color="grey", ls="--", lw=0.8)
        ax.axhline(refs[scene]["relmse_floor"], color="grey", ls=":", lw=0.8, label="reference's own error")
        ax.set_title(f"{scene}, {a.size}x{a.size}, {a.bounces} bounces")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("relMSE vs Mitsuba reference")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, "time_vs_error.png"), dpi=110)


if __name__ == "__main__":
    main()
