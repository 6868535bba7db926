"""Makes tests/data/cornell-box-mitsuba-32.exr and its standard-error image for tests/reference_mitsuba.rs
(and, with `metal`, tests/data/cornell-metal/cornell-metal-mitsuba-32.exr: the box with its tall
block a rough gold conductor, Mitsuba's `roughconductor` with GGX α 0.2, visible-normal sampling
and kdtrace's Au η and κ, two-sided as kdtrace's materials are; with `glass`,
tests/data/cornell-materials/cornell-glass-mitsuba-32.exr: the tall block a rough dielectric,
`roughdielectric` GGX α 0.2, int_ior 1.5, ext_ior 1 (`smooth-glass`: `dielectric`, the same
indices, into cornell-smooth-glass-mitsuba-32.exr); with `plastic`,
tests/data/cornell-materials/cornell-plastic-mitsuba-32.exr: the tall block `plastic` with
diffuse_reflectance (0.7, 0.25, 0.1), int_ior 1.5, ext_ior 1, nonlinear false, two-sided; with
`roughplastic`, cornell-roughplastic-mitsuba-32.exr: the same under `roughplastic`, GGX α 0.2); with `textured`,
tests/data/cornell-textured/cornell-textured-mitsuba-32.exr: the box with a 4x4-texel sRGB poster
on its back wall, Mitsuba's `bitmap` with bilinear filtering and repeat wrapping, raw = false; with
`environment`, tests/data/environment/sky-scene-mitsuba-32.exr: a floor and a block (sky-scene.obj)
under the equirectangular map sky.exr, which this mode writes first (`sky`), Mitsuba's `envmap`
rotated 30 degrees about y as the scene file's `rotate = [0, 30, 0]`, seen from the scene file's
camera).

Mitsuba 3.9 `llvm_ad_rgb` renders our Cornell box (scenes/cornell-box.obj) as render_mitsuba.py
does: 32x32 pixels, 6 bounces (max_depth 8), Cornell's camera (eye 0.278,0.273,0.8, target
0.278,0.273,0, up 0,1,0, vertical fov 39.3076 degrees), box filter. It renders CHUNKS independent
images of SPP_PER_CHUNK samples each (seeds 1000..), and writes
- cornell-box-mitsuba-32.exr: their mean (CHUNKS x SPP_PER_CHUNK samples per pixel);
- cornell-box-mitsuba-32-stderr.exr: the standard error of that mean per pixel channel,
  sqrt(s^2 / CHUNKS) with s^2 the unbiased variance of the chunk means,
so the test can add the reference's own noise to its variance.

Run: DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 \
     bench/.venv/bin/python bench/peers/make_test_reference.py   (bench/peers.sh sets up the venv)
"""
import json
import os
import sys
import tempfile
import time
from types import SimpleNamespace

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)

import numpy as np  # noqa: E402
import mitsuba as mi  # noqa: E402
import objscene  # noqa: E402
import render_mitsuba  # noqa: E402

CHUNKS = 16
SPP_PER_CHUNK = 8192
SIZE = 32


# kdtrace's "Au" (shared::material::CONDUCTOR_PRESETS).
AU_ETA = [0.143119, 0.374957, 1.442479]
AU_K = [3.983160, 2.385721, 1.603215]


def poster(d, tmp, folder):
    """Gives the back wall (the OBJ's material `poster`) its texture: a PLY with the OBJ's planar
    texture coordinates u = x / 0.556, v = y / 0.5488 (cornell-textured.obj), v written as 1 - v
    because Mitsuba's bitmap puts v = 0 at the image's top row (its OBJ loader flips v; its PLY
    loader does not), and a two-sided diffuse reading poster.png as sRGB."""
    key = next(k for k in d if k.endswith("_poster"))
    part = objscene.load(os.path.join(folder, "cornell-textured.obj"))["poster"]
    verts = np.asarray(part["vertices"], dtype="<f4")
    uv = np.stack([verts[:, 0] / np.float32(0.556), 1.0 - verts[:, 1] / np.float32(0.5488)], axis=1)
    ply = os.path.join(tmp, "poster.ply")
    with open(ply, "wb") as f:
        f.write((
            "ply\nformat binary_little_endian 1.0\n"
            f"element vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n"
            "property float u\nproperty float v\n"
            f"element face {len(part['triangles'])}\nproperty list uchar int vertex_indices\nend_header\n"
        ).encode())
        f.write(np.concatenate([verts, uv.astype("<f4")], axis=1).astype("<f4").tobytes())
        faces = np.zeros(len(part["triangles"]), dtype=[("n", "u1"), ("i", "<i4", 3)])
        faces["n"] = 3
        faces["i"] = np.asarray(part["triangles"], dtype="<i4")
        f.write(faces.tobytes())
    texture = {"type": "bitmap", "filename": os.path.join(folder, "poster.png"), "filter_type": "bilinear",
               "wrap_mode": "repeat", "raw": False}
    d[key]["filename"] = ply
    d[key]["bsdf"] = {"type": "twosided", "material": {"type": "diffuse", "reflectance": texture}}


def sky(path):
    """Writes the 64x32 equirectangular test sky (row 0 at the top, +Y; Mitsuba's envmap
    mapping): a blue gradient above the horizon, redder toward u = 1/4 so that a mirrored or
    turned map shows, a brown ground below, and a 2x2-texel sun of radiance (150, 135, 110)."""
    w, h = 64, 32
    img = np.zeros((h, w, 3), dtype=np.float32)
    for y in range(h):
        for x in range(w):
            u, v = (x + 0.5) / w, y / (h - 1)
            if v < 0.5:
                g = 0.4 + 1.2 * (0.5 - v)
                img[y, x] = [0.3 * g * (1.0 + 0.6 * np.sin(2 * np.pi * u)), 0.5 * g, 1.0 * g]
            else:
                img[y, x] = [0.25, 0.2, 0.15]
    img[8:10, 40:42] = [150.0, 135.0, 110.0]
    mi.util.write_bitmap(path, mi.Bitmap(img, pixel_format=mi.Bitmap.PixelFormat.RGB), write_async=False)


def main():
    mi.set_variant("llvm_ad_rgb")
    mode = sys.argv[1] if len(sys.argv) > 1 else "box"
    modes = ("box", "metal", "glass", "smooth-glass", "plastic", "roughplastic", "textured", "environment")
    if mode not in modes:
        sys.exit(f"unknown mode {mode!r}: {', '.join(modes)}")
    env_folder = os.path.join(ROOT, "tests", "data", "environment")
    box = os.path.join(ROOT, "scenes", "cornell-box.obj")
    block = os.path.join(ROOT, "tests", "data", "cornell-metal", "cornell-metal.obj")
    textured_folder = os.path.join(ROOT, "tests", "data", "cornell-textured")
    obj = {"box": box, "textured": os.path.join(textured_folder, "cornell-textured.obj"),
           "environment": os.path.join(env_folder, "sky-scene.obj")}.get(mode, block)
    bsdfs = {}
    if mode == "metal":
        gold = {"type": "roughconductor", "distribution": "ggx", "alpha": 0.2, "sample_visible": True,
                "eta": {"type": "rgb", "value": AU_ETA}, "k": {"type": "rgb", "value": AU_K}}
        bsdfs["gold"] = {"type": "twosided", "material": gold}
    elif mode == "glass":
        bsdfs["gold"] = {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.2, "sample_visible": True,
                         "int_ior": 1.5, "ext_ior": 1.0}
    elif mode == "smooth-glass":
        bsdfs["gold"] = {"type": "dielectric", "int_ior": 1.5, "ext_ior": 1.0}
    elif mode == "plastic":
        plastic = {"type": "plastic", "diffuse_reflectance": {"type": "rgb", "value": [0.7, 0.25, 0.1]},
                   "int_ior": 1.5, "ext_ior": 1.0, "nonlinear": False}
        bsdfs["gold"] = {"type": "twosided", "material": plastic}
    elif mode == "roughplastic":
        plastic = {"type": "roughplastic", "distribution": "ggx", "alpha": 0.2,
                   "diffuse_reflectance": {"type": "rgb", "value": [0.7, 0.25, 0.1]},
                   "int_ior": 1.5, "ext_ior": 1.0, "nonlinear": False}
        bsdfs["gold"] = {"type": "twosided", "material": plastic}
    args = SimpleNamespace(
        scene=obj, width=SIZE, height=SIZE, bounces=6, sampler="independent",
        eye=(0.278, 0.273, 0.8), target=(0.278, 0.273, 0.0), up=(0.0, 1.0, 0.0), fov=39.3076,
    )
    if mode == "environment":
        args.eye, args.target, args.fov = (2.2, 1.0, 2.6), (0.0, 0.5, 0.0), 45.0
        sky(os.path.join(env_folder, "sky.exr"))
    t0 = time.perf_counter()
    chunks = []
    with tempfile.TemporaryDirectory() as tmp:
        d = render_mitsuba.scene_dict(args, tmp, bsdfs)
        if mode == "textured":
            poster(d, tmp, textured_folder)
        if mode == "environment":
            d["sky"] = {"type": "envmap", "filename": os.path.join(env_folder, "sky.exr"),
                        "to_world": mi.ScalarTransform4f().rotate([0, 1, 0], 30)}
        scene = mi.load_dict(d)
        for c in range(CHUNKS):
            img = mi.render(scene, spp=SPP_PER_CHUNK, seed=1000 + c)
            chunks.append(np.asarray(img, dtype=np.float64)[:, :, :3])
    chunks = np.stack(chunks)
    mean = chunks.mean(axis=0)
    stderr = np.sqrt(chunks.var(axis=0, ddof=1) / CHUNKS)
    out, stem = {
        "box": (os.path.join(ROOT, "tests", "data"), "cornell-box-mitsuba-32"),
        "metal": (os.path.join(ROOT, "tests", "data", "cornell-metal"), "cornell-metal-mitsuba-32"),
        "glass": (os.path.join(ROOT, "tests", "data", "cornell-materials"), "cornell-glass-mitsuba-32"),
        "smooth-glass": (os.path.join(ROOT, "tests", "data", "cornell-materials"), "cornell-smooth-glass-mitsuba-32"),
        "plastic": (os.path.join(ROOT, "tests", "data", "cornell-materials"), "cornell-plastic-mitsuba-32"),
        "roughplastic": (os.path.join(ROOT, "tests", "data", "cornell-materials"), "cornell-roughplastic-mitsuba-32"),
        "textured": (textured_folder, "cornell-textured-mitsuba-32"),
        "environment": (env_folder, "sky-scene-mitsuba-32"),
    }[mode]
    os.makedirs(out, exist_ok=True)
    for name, a in [(f"{stem}.exr", mean), (f"{stem}-stderr.exr", stderr)]:
        mi.util.write_bitmap(os.path.join(out, name), mi.Bitmap(a.astype(np.float32), pixel_format=mi.Bitmap.PixelFormat.RGB), write_async=False)
    info = {"renderer": f"mitsuba {mi.__version__} llvm_ad_rgb", "chunks": CHUNKS, "spp_per_chunk": SPP_PER_CHUNK,
            "spp": CHUNKS * SPP_PER_CHUNK, "seconds": time.perf_counter() - t0, "mean": float(mean.mean()),
            "median_relative_stderr": float(np.median(stderr / np.maximum(mean, 1e-6)))}
    print(json.dumps(info))


if __name__ == "__main__":
    main()
