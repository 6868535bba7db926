"""Makes the ꟻLIP reference values that tests/flip_reference.rs checks `kdtrace::metrics` against.

For each image pair in this folder it runs NVIDIA's own ꟻLIP (the `flip-evaluator` package from
PyPI, the official Python binding of the C++ code in github.com/NVlabs/flip) in LDR mode at
67 pixels per degree and stores the mean in expected.json and the per-pixel error map as a
grey little-endian PFM (`<pair>.flip.pfm`).

The pairs:
- cornell-4spp.png vs cornell-1024spp.png: `kdtrace render scenes/cornell-box.obj --width 64
  --height 64 --spp 4` (and 1024), default camera: noise against a converged image.
- pattern-ref.png vs pattern-test.png: written below: a checkerboard with a colour ramp, thin lines
  and dots against a blurred, shifted, recoloured copy, to exercise ꟻLIP's edge and point
  detectors and its colour pipeline.

Run from the repository root: bench/.venv/bin/python tests/data/flip/make_flip_reference.py
(bench/peers.sh sets up that venv; add `pip install flip-evaluator`).
"""
import json
import os

import numpy as np
import flip_evaluator as flip
from PIL import Image

HERE = os.path.dirname(os.path.abspath(__file__))


def patterns():
    h = w = 64
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    ref = np.zeros((h, w, 3))
    ref[..., 0] = ((x // 8 + y // 8) % 2) * 0.8 + 0.1
    ref[..., 1] = x / (w - 1)
    ref[..., 2] = y / (h - 1)
    ref[::9, :, :] = 1.0  # thin lines
    ref[5::11, 7::13, :] = 0.0  # dots
    test = 0.25 * (np.roll(ref, 1, axis=1) + np.roll(ref, -1, axis=0) + 2 * ref)
    test[..., 1] = np.clip(test[..., 1] * 0.9 + 0.05, 0, 1)
    test[20:30, 30:50, :] = [0.9, 0.2, 0.1]
    to8 = lambda a: (np.clip(a, 0, 1) * 255 + 0.5).astype(np.uint8)
    Image.fromarray(to8(ref)).save(os.path.join(HERE, "pattern-ref.png"))
    Image.fromarray(to8(test)).save(os.path.join(HERE, "pattern-test.png"))


def write_pfm_grey(path, a):
    h, w = a.shape
    with open(path, "wb") as f:
        f.write(f"Pf\n{w} {h}\n-1.0\n".encode())
        f.write(np.ascontiguousarray(a[::-1], dtype="<f4").tobytes())


def main():
    patterns()
    expected = {"flip_evaluator": "1.7", "ppd": 67.0, "pairs": {}}
    for name, ref, test in [("cornell", "cornell-1024spp.png", "cornell-4spp.png"), ("pattern", "pattern-ref.png", "pattern-test.png")]:
        r = np.asarray(Image.open(os.path.join(HERE, ref)).convert("RGB"), dtype=np.float32) / 255.0
        t = np.asarray(Image.open(os.path.join(HERE, test)).convert("RGB"), dtype=np.float32) / 255.0
        err, mean, _ = flip.evaluate(r, t, "LDR", inputsRGB=True, applyMagma=False, parameters={"ppd": 67.0})
        err = np.asarray(err, dtype=np.float32).reshape(r.shape[0], r.shape[1], -1)[..., 0]
        write_pfm_grey(os.path.join(HERE, f"{name}.flip.pfm"), err)
        expected["pairs"][name] = {"reference": ref, "test": test, "mean": float(mean), "max": float(err.max())}
        print(name, mean, err.max())
    with open(os.path.join(HERE, "expected.json"), "w") as f:
        json.dump(expected, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
