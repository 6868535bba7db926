"""Ray-casting throughput of Embree through Mitsuba 3 (`llvm_ad_rgb`), for the rays `kdtrace rays`
casts: primary rays through the pixel centres of a pinhole camera, then cosine-distributed
diffuse rays from their hits (closest hit both). The figure to hold `kdtrace rays` against.

Usage (after bench/peers.sh has made the venv; DRJIT_LIBLLVM_PATH set as it sets it):
  bench/.venv/bin/python bench/peers/embree_rays.py SCENE.obj EYE TARGET FOV [SIZE [THREADS]]
  e.g. ... bench/results/scenes/sponza-sky.obj -11,3,0 11,5,0 55 512 1

THREADS (default: as drjit picks them, one per core) sets drjit's thread count. With THREADS = 1
and the `embreex` package installed in the venv (`pip install embreex`: Embree 2.17 behind a
Cython loop), the same rays are also cast one at a time through `rtcIntersect1`, single-ray
traversal as kdtrace does it (the loop's per-ray overhead included). With THREADS = 1 the rays
(the first 65,536 of each kind) also go one call at a time through Mitsuba's `scalar_rgb` variant,
whose `ray_intersect_preliminary` is Embree 4's `rtcIntersect1` on the same BVH Mitsuba builds:
the figure is net of the Python call, timed on as many rays that start outside the scene's box
and point away from it.

Mitsuba loads the OBJ as one mesh (Embree builds its BVH over it); the diffuse rays start 1e-4
off each hit along its normal, turned toward the camera. Fastest of four timed runs of
`ray_intersect_preliminary` each, `dr.eval` forcing the work; 2 threads as drjit picks them.
The diffuse directions are not kdtrace's own random numbers: compare rates, not rays.
"""
import math
import sys
import time

import drjit as dr
import mitsuba as mi
import numpy as np


def vec(s):
    return np.array([float(x) for x in s.split(",")])


def best_rate(fn, n, runs=4):
    best = math.inf
    for _ in range(runs):
        t0 = time.perf_counter()
        r = fn()
        dr.eval(r)
        dr.sync_thread()
        best = min(best, time.perf_counter() - t0)
    return n / best / 1e6


def main():
    mi.set_variant("llvm_ad_rgb")
    obj, eye, target, fov = sys.argv[1], vec(sys.argv[2]), vec(sys.argv[3]), float(sys.argv[4])
    size = int(sys.argv[5]) if len(sys.argv) > 5 else 512
    threads = int(sys.argv[6]) if len(sys.argv) > 6 else None
    if threads:
        dr.set_thread_count(threads)
    scene = mi.load_dict({"type": "scene", "mesh": {"type": "obj", "filename": obj}})
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    t = math.tan(math.radians(fov) / 2)
    i, j = np.meshgrid(np.arange(size), np.arange(size))
    x = ((i + 0.5) / size * 2 - 1) * t
    y = (1 - (j + 0.5) / size * 2) * t
    d = forward[None, None, :] + x[..., None] * right + y[..., None] * up
    d = (d / np.linalg.norm(d, axis=-1, keepdims=True)).reshape(-1, 3).astype(np.float32)
    n = size * size
    origin = mi.Point3f(*[np.full(n, c, dtype=np.float32) for c in eye])
    primary = mi.Ray3f(origin, mi.Vector3f(d[:, 0], d[:, 1], d[:, 2]))
    rate_primary = best_rate(lambda: scene.ray_intersect_preliminary(primary), n)
    si = scene.ray_intersect(primary)
    rng = np.random.default_rng(1)
    u = mi.Point2f(mi.Float(rng.random(n, dtype=np.float32)), mi.Float(rng.random(n, dtype=np.float32)))
    normal = dr.select(dr.dot(si.n, primary.d) > 0, -si.n, si.n)
    direction = mi.Frame3f(normal).to_world(mi.warp.square_to_cosine_hemisphere(u))
    diffuse = mi.Ray3f(si.p + normal * 1e-4, direction)
    dr.eval(diffuse)
    hits = int(np.count_nonzero(np.array(si.is_valid())))
    rate_diffuse = best_rate(lambda: scene.ray_intersect_preliminary(diffuse), n)
    print(f"Embree via Mitsuba {mi.__version__}, {size}x{size}, {dr.thread_count()} threads: primary {rate_primary:.2f} Mrays/s, "
          f"diffuse {rate_diffuse:.2f} Mrays/s (from {hits} primary hits; misses cast too)")
    if threads == 1:
        # drjit's vectors convert to arrays of three rows; the single-ray loops take one row a ray.
        diffuse_o, diffuse_d = [np.ascontiguousarray(np.array(v, dtype=np.float32).T) for v in (diffuse.o, diffuse.d)]
        single_rays(scene, eye, d, diffuse_o, diffuse_d, n)
        scalar_rays(obj, eye, d, diffuse_o, diffuse_d)


SCALAR_RAYS = 1 << 16


def scalar_rays(obj, eye, d, diffuse_o, diffuse_d):
    """Embree 4 single rays through Mitsuba's scalar variant, net of the per-call overhead."""
    mi.set_variant("scalar_rgb")
    scene = mi.load_dict({"type": "scene", "mesh": {"type": "obj", "filename": obj}})
    n = min(SCALAR_RAYS, len(d))
    primary = [mi.Ray3f(mi.Point3f(*eye), mi.Vector3f(*d[i])) for i in range(n)]
    bounce = [mi.Ray3f(mi.Point3f(*diffuse_o[i]), mi.Vector3f(*diffuse_d[i])) for i in range(n)]
    lo, hi = scene.bbox().min, scene.bbox().max
    outside = mi.Point3f(lo.x, hi.y + 1.0, lo.z)
    away = [mi.Ray3f(outside, mi.Vector3f(0, 1, 0)) for _ in range(n)]
    cast = scene.ray_intersect_preliminary

    def seconds_per_ray(rays):
        def loop():
            for r in rays:
                cast(r)
        return 1e-6 / best_rate(loop, len(rays))

    call, t_primary, t_diffuse = seconds_per_ray(away), seconds_per_ray(primary), seconds_per_ray(bounce)
    print(f"Embree in Mitsuba {mi.__version__}, scalar variant (rtcIntersect1), 1 thread, first {n} rays, net of "
          f"{call * 1e9:.0f} ns a call: primary {1e-6 / (t_primary - call):.2f} Mrays/s, "
          f"diffuse {1e-6 / (t_diffuse - call):.2f} Mrays/s")


def single_rays(scene, eye, d, diffuse_o, diffuse_d, n):
    try:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh
    except ImportError:
        print("embreex not installed: no single-ray figures")
        return
    mesh = scene.shapes()[0]
    vertices = np.array(mesh.vertex_positions_buffer()).reshape(-1, 3)
    faces = np.array(mesh.faces_buffer()).reshape(-1, 3)
    single = rtcore_scene.EmbreeScene()
    TriangleMesh(single, vertices[faces].astype(np.float32))

    origins = np.tile(eye.astype(np.float32), (n, 1))
    primary = best_rate(lambda: single.run(origins, d), n)
    diffuse_rate = best_rate(lambda: single.run(diffuse_o, diffuse_d), n)
    print(f"Embree 2.17 rtcIntersect1 (embreex), 1 thread: primary {primary:.2f} Mrays/s, "
          f"diffuse {diffuse_rate:.2f} Mrays/s")


if __name__ == "__main__":
    main()
