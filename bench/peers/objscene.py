"""The scene exactly as `kdtrace render` sees it, for the peer renderers' drivers.

kdtrace loads OBJ + MTL with tobj (host/src/scene/obj.rs): polygons are triangulated as fans from the
first vertex, `Kd` is the Lambertian albedo, `Ke` the emitted radiance (one-sided, from the side the
normal (v1 - v0) x (v2 - v0) points to), and a missing or unknown material is grey 0.5 diffuse.
This module reads the same files the same way and returns the triangles split by material, so the
Cycles and Mitsuba drivers can give each part a diffuse BSDF and, where `Ke` is non-zero, an
emitter. It also holds the shared command line (camera, resolution, spp, bounces, seed).
"""
import argparse
import os

DEFAULT_ALBEDO = (0.5, 0.5, 0.5)


def _vec3(s):
    parts = s.split(",")
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"expected x,y,z, got {s!r}")
    return tuple(float(p) for p in parts)


def parse_args(description, extra=None):
    p = argparse.ArgumentParser(description=description)
    if extra:
        extra(p)
    p.add_argument("scene", help="OBJ file (with its MTL beside it)")
    p.add_argument("--out", required=True, help="linear 32-bit float EXR to write")
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--width", type=int, default=256)
    p.add_argument("--height", type=int, default=256)
    p.add_argument("--bounces", type=int, default=6, help="indirect bounces, as kdtrace's --bounces")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--eye", type=_vec3, required=True)
    p.add_argument("--target", type=_vec3, required=True)
    p.add_argument("--up", type=_vec3, required=True)
    p.add_argument("--fov", type=float, required=True, help="vertical field of view in degrees")
    p.add_argument("--json", action="store_true", help="print one JSON line")
    return p.parse_args()


def _read_mtl(path):
    mats, cur = {}, None
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            t = line.split()
            if not t or t[0].startswith("#"):
                continue
            if t[0] == "newmtl":
                cur = " ".join(t[1:])
                mats[cur] = {"Kd": DEFAULT_ALBEDO, "Ke": (0.0, 0.0, 0.0)}
            elif cur is not None and t[0] in ("Kd", "Ke") and len(t) >= 4:
                mats[cur][t[0]] = tuple(float(x) for x in t[1:4])
    return mats


def records(path):
    """The OBJ's statements in order: ("v", (x, y, z)), ("f", [0-based vertex indices]),
    ("mtllib", path), ("usemtl", name); everything else is skipped."""
    count = 0
    base = os.path.dirname(os.path.abspath(path))
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            t = line.split()
            if not t:
                continue
            if t[0] == "v":
                count += 1
                yield "v", tuple(float(x) for x in t[1:4])
            elif t[0] == "mtllib":
                yield "mtllib", os.path.join(base, " ".join(t[1:]))
            elif t[0] == "usemtl":
                yield "usemtl", " ".join(t[1:])
            elif t[0] == "f":
                idx = []
                for tok in t[1:]:
                    i = int(tok.split("/")[0])
                    idx.append(i - 1 if i > 0 else count + i)
                yield "f", idx


def load(path, drop_coincident=False):
    """Returns {material name: {"Kd", "Ke", "vertices": [(x,y,z)], "triangles": [(i,j,k)]}}.

    With `drop_coincident`, a triangle whose three corners (in any order) are those of a triangle
    met before is left out: for opaque two-sided surfaces a coincident twin changes nothing, as
    a ray hits one of the two, but a renderer whose rays skip only the triangle they leave (Cycles)
    finds the twin at distance zero and shadows the face. CornellBox-Original's "bottom" faces of
    the two blocks repeat a side face's corners, and uneven-noise's partition is two faces of
    opposite winding."""
    verts, mats, parts = [], {}, {}
    seen = set()
    current = None
    for kind, value in records(path):
        if kind == "v":
            verts.append(value)
        elif kind == "mtllib":
            if os.path.exists(value):
                mats.update(_read_mtl(value))
        elif kind == "usemtl":
            current = value
        else:
            name = current if current in mats else None
            part = parts.setdefault(name, {"triangles": []})
            for k in range(1, len(value) - 1):
                tri = (value[0], value[k], value[k + 1])
                if drop_coincident:
                    key = frozenset(verts[i] for i in tri)
                    if key in seen:
                        continue
                    seen.add(key)
                part["triangles"].append(tri)
    out = {}
    for name, part in parts.items():
        m = mats.get(name, {"Kd": DEFAULT_ALBEDO, "Ke": (0.0, 0.0, 0.0)})
        used = sorted({i for tri in part["triangles"] for i in tri})
        remap = {old: new for new, old in enumerate(used)}
        out[name or "default"] = {
            "Kd": m["Kd"],
            "Ke": m["Ke"],
            "vertices": [verts[i] for i in used],
            "triangles": [tuple(remap[i] for i in tri) for tri in part["triangles"]],
        }
    return out
