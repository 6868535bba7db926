"""The bias of adaptive sampling's modes, measured: many seeds of each mode, averaged, against a
converged fixed-sample render of the same scene (fixed sampling is unbiased; it passes the
per-pixel test against Mitsuba in tests/reference_mitsuba.rs).

Per mode: the relative bias of the image mean (mean over seeds and pixels, against the
reference's), and per pixel the bias (seed average minus reference) with its t statistic
(bias over the standard error of the seed average and the reference's own): the worst pixel by
|t|, its relative bias, and how many pixels exceed |t| > 4. An unbiased mode shows a mean bias
within its standard error and no pixel far beyond what K seeds allow.

Usage: bench/.venv/bin/python bench/adaptive_bias.py [--scene scenes/uneven-noise.toml]
[--size 64x48] [--seeds 32] [--threshold 0.05] [--ref-spp 32768]; prints a Markdown table and
writes bench/results/adaptive_bias.json.
"""
import argparse
import json
import os
import subprocess
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
KDTRACE = os.path.join(ROOT, "target", "release", "kdtrace")


def render(scene, out, size, args):
    w, h = size
    cmd = [KDTRACE, "render", scene, "--out", out, "--width", str(w), "--height", str(h), "--json"] + args
    p = subprocess.run(cmd, capture_output=True, text=True, check=True)
    return json.loads(p.stdout.strip().splitlines()[-1])


def read(path):
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    return np.asarray(mi.Bitmap(path), dtype=np.float64)[:, :, :3]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=os.path.join(ROOT, "scenes", "uneven-noise.toml"))
    ap.add_argument("--size", default="64x48")
    ap.add_argument("--seeds", type=int, default=32)
    ap.add_argument("--threshold", type=float, default=0.05)
    ap.add_argument("--max-spp", type=int, default=4096)
    ap.add_argument("--ref-spp", type=int, default=32768)
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    a = ap.parse_args()
    size = tuple(int(v) for v in a.size.split("x"))
    os.makedirs(a.out, exist_ok=True)
    tmp = tempfile.mkdtemp()
    ref_path = os.path.join(tmp, "ref.exr")
    ref_var_path = os.path.join(tmp, "ref-var.exr")
    render(a.scene, ref_path, size, ["--spp", str(a.ref_spp), "--seed", "1000003", "--variance", ref_var_path])
    ref = read(ref_path)
    ref_se2 = read(ref_var_path) / a.ref_spp
    results = {}
    for mode in ["pilot", "as-you-go"]:
        images, spp = [], []
        for seed in range(1, a.seeds + 1):
            out = os.path.join(tmp, f"{mode}-{seed}.exr")
            j = render(a.scene, out, size, ["--spp", str(a.max_spp), "--seed", str(seed), "--adaptive", str(a.threshold),
                                            "--adaptive-mode", mode])
            images.append(read(out))
            spp.append(j["spp_mean"])
        x = np.stack(images)
        k = len(images)
        avg = x.mean(axis=0)
        se2 = x.var(axis=0, ddof=1) / k + ref_se2
        bias = avg - ref
        t = bias / np.sqrt(np.maximum(se2, 1e-30))
        image_bias = avg.mean() / ref.mean() - 1.0
        # The image mean's standard error from the seeds' image means.
        image_se = x.mean(axis=(1, 2, 3)).std(ddof=1) / np.sqrt(k) / ref.mean()
        lum = ref.mean(axis=2)
        worst = np.unravel_index(np.argmax(np.abs(t)), t.shape)
        results[mode] = {
            "seeds": k,
            "spp_mean": float(np.mean(spp)),
            "image_relative_bias": float(image_bias),
            "image_relative_bias_se": float(image_se),
            "worst_pixel": [int(worst[1]), int(worst[0]), int(worst[2])],
            "worst_t": float(t[worst]),
            "worst_relative_bias": float(bias[worst] / max(ref[worst], 1e-6)),
            "worst_pixel_reference": float(ref[worst]),
            "pixels_beyond_t4": int((np.abs(t) > 4).sum()),
            "mean_abs_relative_bias": float((np.abs(bias.mean(axis=2)) / np.maximum(lum, 1e-3)).mean()),
            "channel_values": int(t.size),
        }
    with open(os.path.join(a.out, "adaptive_bias.json"), "w") as f:
        json.dump({"scene": os.path.relpath(a.scene, ROOT), "size": a.size, "threshold": a.threshold, "ref_spp": a.ref_spp, "modes": results}, f, indent=1)
    print(f"{os.path.basename(a.scene)}, {a.size}, threshold {a.threshold}, {a.seeds} seeds, reference {a.ref_spp} spp fixed")
    print("| mode | mean spp | image mean bias | worst pixel (x, y, channel): bias, t | channel values with abs(t) > 4 |")
    print("|---|---|---|---|---|")
    for mode, r in results.items():
        print(f"| {mode} | {r['spp_mean']:.1f} | {100 * r['image_relative_bias']:+.2f}% ± {100 * r['image_relative_bias_se']:.2f}% "
              f"| {tuple(r['worst_pixel'])}: {100 * r['worst_relative_bias']:+.1f}%, t = {r['worst_t']:.1f} "
              f"| {r['pixels_beyond_t4']} of {r['channel_values']} |")


if __name__ == "__main__":
    main()
