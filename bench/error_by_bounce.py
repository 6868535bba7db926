"""Where a scene's error comes from: kdtrace's relMSE at one sample count as the bounce limit
rises, with and without the connections, and the time each takes.

Each row renders the scene twice with the same settings and different seeds; the two images are
independent estimates of one image, so half their mean squared difference is one render's
error (no reference needed). Every row is scored over the same denominator, the mean of the
full-depth pair squared plus 0.01 (as `kdtrace compare`'s relMSE), so the rows add up: the
difference between two bounce limits is the error the extra bounces bring. The second part
tells which pixels carry the error: its share in the brightest-error 1% and 10% of pixels and
by the reference's luminance.

Usage (the bench venv, for Mitsuba's EXR reader):
  bench/.venv/bin/python bench/error_by_bounce.py SCENE.obj --spp 256 --size 256 CAMERA-FLAGS...
e.g. sponza-sky from the atrium: `--eye=-11,3,0 --target=11,5,0 --up=0,1,0 --fov=55`. The
environment variable KDTRACE names another binary to measure.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

import mitsuba as mi
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
KDTRACE = os.environ.get("KDTRACE", os.path.join(ROOT, "target", "release", "kdtrace"))
mi.set_variant("scalar_rgb")


def render(scene, out, spp, size, bounces, seed, connect, camera):
    cmd = [KDTRACE, "render", scene, "--out", out, "--spp", str(spp), "--width", str(size), "--height", str(size),
           "--bounces", str(bounces), "--seed", str(seed), "--connect", connect] + camera
    log = subprocess.run(cmd, check=True, capture_output=True, text=True).stderr
    return float(re.search(r"render ([0-9.]+) s", log).group(1))


def read(path):
    return np.array(mi.Bitmap(path)).astype(np.float64)[..., :3]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--bounces", default="0,1,2,6")
    a, camera = ap.parse_known_args()
    camera = [c for c in camera if c != "--"]
    limits = [int(b) for b in a.bounces.split(",")]
    rows = [(b, "auto") for b in limits] + [(max(limits), "off")]
    with tempfile.TemporaryDirectory() as tmp:
        images, times = {}, {}
        for b, connect in rows:
            pair = []
            for seed in (1, 2):
                out = os.path.join(tmp, f"b{b}-{connect}-s{seed}.exr")
                times.setdefault((b, connect), []).append(render(a.scene, out, a.spp, a.size, b, seed, connect, camera))
                pair.append(read(out))
            images[(b, connect)] = pair
        full = images[(max(limits), "auto")]
        mean = 0.5 * (full[0] + full[1])
        den = mean**2 + 1e-2
        lum = mean.mean(-1).ravel()
        print(f"{a.scene}, {a.size}x{a.size}, {a.spp} spp, two seeds a row")
        print("| bounces | connect | relMSE of one render | render s (mean of two) | top 1% of pixels | top 10% |")
        print("|---|---|---|---|---|---|")
        for b, connect in rows:
            x, y = images[(b, connect)]
            e = (((x - y) ** 2 / den).mean(-1) / 2).ravel()
            s = np.sort(e)[::-1]
            n = len(s)
            print(f"| {b} | {connect} | {e.mean():.3e} | {np.mean(times[(b, connect)]):.2f} "
                  f"| {s[: n // 100].sum() / s.sum():.2f} | {s[: n // 10].sum() / s.sum():.2f} |")
        x, y = images[(max(limits), "auto")]
        e = (((x - y) ** 2 / den).mean(-1) / 2).ravel()
        print("\n| reference luminance | pixels | share of the error |\n|---|---|---|")
        for lo, hi in [(0, 0.05), (0.05, 0.1), (0.1, 0.2), (0.2, 0.5), (0.5, 1), (1, np.inf)]:
            m = (lum >= lo) & (lum < hi)
            print(f"| [{lo}, {hi}) | {100 * m.mean():.1f}% | {100 * e[m].sum() / e.sum():.1f}% |")


if __name__ == "__main__":
    sys.exit(main())
