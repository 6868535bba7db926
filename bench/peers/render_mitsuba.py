"""Render an OBJ scene with Mitsuba 3 (`llvm_ad_rgb`) exactly as `kdtrace render` does.

Same triangles split by material (objscene.py), a two-sided `diffuse` BSDF with albedo Kd (kdtrace's
diffuse reflects on both sides, Mitsuba's only on the front), an `area` emitter with radiance Ke
(Mitsuba area lights emit from the front, the counter-clockwise side, as kdtrace does), face
normals, black environment, `path` integrator with max_depth = bounces + 2 and Russian roulette
from depth 5 (kdtrace's rr_start), box pixel filter, independent sampler (Mitsuba's default;
`--sampler ldsampler` for its padded (0,2)-sequence sampler), pinhole camera from
eye/target/up with the vertical field of view. Writes a linear float32 RGB EXR.

Large sample counts are rendered in passes of at most 2^24 samples (Mitsuba's LLVM backend keeps
one wavefront of all samples in memory) with distinct seeds, and averaged.

Needs DRJIT_LIBLLVM_PATH pointing at LLVM >= 16 (bench/peers.sh sets it).
"""
import json
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import objscene  # noqa: E402

import numpy as np  # noqa: E402
import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

MAX_PASS_SAMPLES = 1 << 24


def write_ply(path, verts, tris):
    with open(path, "wb") as f:
        f.write(
            (
                "ply\nformat binary_little_endian 1.0\n"
                f"element vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n"
                f"element face {len(tris)}\nproperty list uchar int vertex_indices\nend_header\n"
            ).encode()
        )
        f.write(np.asarray(verts, dtype="<f4").tobytes())
        faces = np.zeros(len(tris), dtype=[("n", "u1"), ("i", "<i4", 3)])
        faces["n"] = 3
        faces["i"] = np.asarray(tris, dtype="<i4")
        f.write(faces.tobytes())


def scene_dict(args, tmp, bsdfs=None):
    """The scene as a Mitsuba dict: every OBJ part a two-sided diffuse of its `Kd` (and an area
    emitter of its `Ke`), except the parts named in `bsdfs`, which get that Mitsuba BSDF dict."""
    bsdfs = bsdfs or {}
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": args.bounces + 2, "rr_depth": 5, "hide_emitters": False},
        "sensor": {
            "type": "perspective",
            "fov": args.fov,
            "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(origin=args.eye, target=args.target, up=args.up),
            # render(spp=...) sets the count; 4 is one ldsampler accepts without a warning.
            "sampler": {"type": args.sampler, "sample_count": 4},
            "film": {
                "type": "hdrfilm",
                "width": args.width,
                "height": args.height,
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
                "component_format": "float32",
            },
        },
    }
    for n, (name, part) in enumerate(objscene.load(args.scene).items()):
        ply = os.path.join(tmp, f"part{n}.ply")
        write_ply(ply, part["vertices"], part["triangles"])
        shape = {
            "type": "ply",
            "filename": ply,
            "face_normals": True,
            "bsdf": bsdfs.get(name, {"type": "twosided", "material": {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(part["Kd"])}}}),
        }
        if max(part["Ke"]) > 0:
            shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": list(part["Ke"])}}
        d[f"part{n}_{name}"] = shape
    return d


def main():
    args = objscene.parse_args(__doc__.splitlines()[0], lambda p: p.add_argument("--sampler", default="independent", help="Mitsuba sampler plugin"))
    mi.set_variant("llvm_ad_rgb")
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        scene = mi.load_dict(scene_dict(args, tmp))
        load_s = time.perf_counter() - t0
        per_pass = max(1, min(args.spp, MAX_PASS_SAMPLES // (args.width * args.height)))
        # A low-discrepancy sampler stratifies within one pass: keep passes power-of-two sized.
        if args.sampler != "independent":
            per_pass = 1 << (per_pass.bit_length() - 1)
        acc = np.zeros((args.height, args.width, 3), dtype=np.float64)
        done, passes = 0, 0
        t1 = time.perf_counter()
        while done < args.spp:
            n = min(per_pass, args.spp - done)
            img = mi.render(scene, spp=n, seed=args.seed * 100003 + passes)
            acc += np.asarray(img, dtype=np.float64)[:, :, :3] * n
            done += n
            passes += 1
        render_s = time.perf_counter() - t1
    out = (acc / args.spp).astype(np.float32)
    mi.util.write_bitmap(args.out, mi.Bitmap(out, pixel_format=mi.Bitmap.PixelFormat.RGB), write_async=False)
    line = {
        "renderer": f"mitsuba {mi.__version__} llvm_ad_rgb", "sampler": args.sampler, "scene": args.scene, "out": args.out,
        "spp": args.spp, "width": args.width, "height": args.height, "bounces": args.bounces,
        "passes": passes, "load_s": load_s, "render_s": render_s, "threads": dr.thread_count(),
    }
    print(json.dumps(line) if args.json else line)


if __name__ == "__main__":
    main()
