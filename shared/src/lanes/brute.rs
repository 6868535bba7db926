//! Sixteen rays against every triangle of a small scene, one ray per lane: the watertight test
//! (`triangle::RayShear`, Woop, Benthin & Wald 2013) transposed, so that one triangle is tested
//! against sixteen rays at once.
//!
//! A wide BVH over a few dozen triangles is one node over a handful of leaf blocks, and a ray's
//! traversal there is mostly its fixed cost: the shear, the reciprocal, the node's box test, the
//! ordering of the children, one or two leaf blocks. Testing all the triangles against the
//! sixteen rays of a group costs a few dozen vector steps per triangle, shared by the sixteen,
//! and no branch depends on a box. It wins where the triangles are few for the rays still
//! live in the group (`TRIANGLES_PER_RAY`): as paths end, the rest go back to the traversal.
//!
//! Each lane performs the operations `RayShear::new` and `RayShear::intersect` perform for its
//! ray, in their order, and keeps the closest hit in (0, t_max) with the lowest triangle id on a
//! tie, testing the triangles in id order: what the wide BVH's traversal returns (`wide_bvh`,
//! equal to brute force bit for bit). The axes of a ray's shear differ from lane to lane, so a
//! triangle's coordinates are picked per lane by masks.
#[cfg(test)]
use super::LANES;
use super::{Hits, F, M, U, V3};
use crate::layout::{Triangle, NO_HIT};
use core::simd::cmp::{SimdPartialEq, SimdPartialOrd};
use core::simd::num::SimdFloat;
use core::simd::Select;

/// A group's rays are cast by brute force where the scene has at most this many triangles per
/// ray to cast. Measured on the 2-core AMD VM (BENCHMARKS.md, "The lane integrator"), six bounces,
/// alternating runs: on CornellBox-Original's 36 triangles 3 and 8 were within 4% of each other and
/// 4% faster than brute force for any number of rays; uneven-noise's 18 did not tell them apart.
pub const TRIANGLES_PER_RAY: usize = 6;

/// Whether brute force over `triangles` pays for the live lanes' rays (`TRIANGLES_PER_RAY`).
#[inline(always)]
pub fn pays(triangles: usize, live: M) -> bool {
    triangles <= live.to_bitmask().count_ones() as usize * TRIANGLES_PER_RAY
}

/// `x` where `k` is 0, `y` where 1, `z` where 2, lane by lane.
#[inline(always)]
fn pick(k0: M, k1: M, x: F, y: F, z: F) -> F {
    k0.select(x, k1.select(y, z))
}

/// Per-lane `RayShear` constants.
struct Shear {
    usable: M,
    kx: (M, M),
    ky: (M, M),
    kz: (M, M),
    o: (F, F, F),
    sx: F,
    sy: F,
    sz: F,
}

/// `kdtree::usable_direction`, then `RayShear::new`, lane by lane.
#[inline(always)]
fn shear(origin: V3, dir: V3) -> Shear {
    let zero = F::splat(0.0);
    // `kdtree::flush_denormals`.
    let flush = |x: F| x.abs().simd_lt(F::splat(f32::MIN_POSITIVE)).select(zero, x);
    let d = V3::new(flush(dir.x), flush(dir.y), flush(dir.z));
    let finite = |v: V3| v.x.is_finite() & v.y.is_finite() & v.z.is_finite();
    let zero_dir = d.x.simd_eq(zero) & d.y.simd_eq(zero) & d.z.simd_eq(zero);
    let usable = finite(origin) & finite(d) & !zero_dir;
    let (ax, ay, az) = (d.x.abs(), d.y.abs(), d.z.abs());
    let z_is_x = ax.simd_ge(ay) & ax.simd_ge(az);
    let z_is_y = !z_is_x & ay.simd_ge(az);
    let kz = z_is_x.select(U::splat(0), z_is_y.select(U::splat(1), U::splat(2)));
    let kx = kz.simd_eq(U::splat(2)).select(U::splat(0), kz + U::splat(1));
    let ky = kx.simd_eq(U::splat(2)).select(U::splat(0), kx + U::splat(1));
    let dz = pick(z_is_x, z_is_y, d.x, d.y, d.z);
    let flip = dz.simd_lt(zero);
    let (kx, ky) = (flip.select(ky, kx), flip.select(kx, ky));
    let masks = |k: U| (k.simd_eq(U::splat(0)), k.simd_eq(U::splat(1)));
    let (kx, ky, kz) = (masks(kx), masks(ky), masks(kz));
    let sz = F::splat(1.0) / dz;
    let at = |k: (M, M), v: V3| pick(k.0, k.1, v.x, v.y, v.z);
    Shear {
        usable,
        kx,
        ky,
        kz,
        o: (at(kx, origin), at(ky, origin), at(kz, origin)),
        sx: at(kx, d) * sz,
        sy: at(ky, d) * sz,
        sz,
    }
}

/// The closest hit in (0, t_max) among `triangles` of each live lane's ray, or with `any_hit`
/// whether there is one (the triangle of some hit: the lowest id that hits). A triangle's id is
/// its position, or where `ids` is not empty the entry of `ids` there (ascending, so that the
/// tie rule still keeps the lowest id).
#[inline(always)]
pub fn cast(triangles: &[Triangle], ids: &[u32], origin: V3, dir: V3, t_max: F, live: M, any_hit: bool) -> Hits {
    let s = shear(origin, dir);
    let zero = F::splat(0.0);
    let mut open = live & s.usable;
    let mut best = Hits { triangle: U::splat(NO_HIT), t: t_max, u: zero, v: zero, w: zero };
    for (id, tri) in triangles.iter().enumerate() {
        if !open.any() {
            break;
        }
        // One vertex in each lane's sheared frame: (x, y) and the distance coordinate.
        let vertex = |p: crate::glam::Vec4| {
            let (x, y, z) = (F::splat(p.x), F::splat(p.y), F::splat(p.z));
            let kz = pick(s.kz.0, s.kz.1, x, y, z) - s.o.2;
            let vx = (pick(s.kx.0, s.kx.1, x, y, z) - s.o.0) - s.sx * kz;
            let vy = (pick(s.ky.0, s.ky.1, x, y, z) - s.o.1) - s.sy * kz;
            (vx, vy, kz)
        };
        let (ax, ay, akz) = vertex(tri.v0);
        let (bx, by, bkz) = vertex(tri.v1);
        let (cx, cy, ckz) = vertex(tri.v2);
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        let any_neg = u.simd_lt(zero) | v.simd_lt(zero) | w.simd_lt(zero);
        let any_pos = u.simd_gt(zero) | v.simd_gt(zero) | w.simd_gt(zero);
        let det = u + v + w;
        let inside = !(any_neg & any_pos) & det.simd_ne(zero) & open;
        if !inside.any() {
            continue;
        }
        let t = (u * (s.sz * akz) + v * (s.sz * bkz) + w * (s.sz * ckz)) / det;
        let hit = inside & t.simd_gt(zero) & t.simd_lt(best.t);
        let id = if ids.is_empty() { id as u32 } else { ids[id] };
        best.triangle = hit.select(U::splat(id), best.triangle);
        best.t = hit.select(t, best.t);
        best.u = hit.select(u, best.u);
        best.v = hit.select(v, best.v);
        best.w = hit.select(w, best.w);
        if any_hit {
            open &= !hit;
        }
    }
    best
}

/// The lanes' rays as `LANES` single rays, for tests.
#[cfg(test)]
fn lanes_of(v: V3) -> [crate::glam::Vec3; LANES] {
    core::array::from_fn(|i| v.lane(i))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::glam::{Vec3, Vec4};
    use crate::rng::pcg4d;
    use crate::triangle::RayShear;

    fn r(key: u32, k: u32) -> f32 {
        (pcg4d(key, k, 0x99, 3)[0] >> 8) as f32 / 16_777_216.0
    }

    /// Brute force one ray at a time with the scalar test, closest hit and lowest id on a tie.
    fn scalar(tris: &[Triangle], o: Vec3, d: Vec3, t_max: f32) -> (u32, f32, f32, f32, f32) {
        let mut best = (NO_HIT, t_max, 0.0, 0.0, 0.0);
        let d = crate::kdtree::flush_denormals(d);
        let ok = crate::numerics::is_finite3(o) & crate::numerics::is_finite3(d) & (d != Vec3::ZERO);
        if !ok {
            return best;
        }
        let s = RayShear::new(o, d);
        for (id, t) in tris.iter().enumerate() {
            if let Some(h) = s.intersect(t, 0.0, best.1) {
                best = (id as u32, h.t, h.u, h.v, h.w);
            }
        }
        best
    }

    #[test]
    fn lanes_find_what_the_scalar_test_finds() {
        // A closed box of twelve triangles, two coincident faces, a sliver and a triangle
        // crossing the others; rays from inside and outside, along axes, through vertices.
        let q = |a: [f32; 3], b: [f32; 3], c: [f32; 3]| Triangle {
            v0: Vec4::new(a[0], a[1], a[2], 0.0),
            v1: Vec4::new(b[0], b[1], b[2], 0.0),
            v2: Vec4::new(c[0], c[1], c[2], 0.0),
        };
        let mut tris = Vec::new();
        for axis in 0..3 {
            for side in [-1.0f32, 1.0] {
                let p = |u: f32, v: f32| {
                    let mut x = [0.0; 3];
                    x[axis] = side;
                    x[(axis + 1) % 3] = u;
                    x[(axis + 2) % 3] = v;
                    x
                };
                tris.push(q(p(-1.0, -1.0), p(1.0, -1.0), p(1.0, 1.0)));
                tris.push(q(p(-1.0, -1.0), p(1.0, 1.0), p(-1.0, 1.0)));
            }
        }
        tris.push(q([-0.5, 0.0, -0.5], [0.5, 0.0, -0.5], [0.0, 0.0, 0.5]));
        tris.push(q([-0.5, 0.0, -0.5], [0.5, 0.0, -0.5], [0.0, 0.0, 0.5]));
        tris.push(q([-0.9, -0.9, 0.0], [0.9, 0.9, 0.0], [0.9, 0.9, 1e-7]));
        tris.push(q([0.0, -0.8, -0.8], [0.0, 0.8, 0.0], [0.3, 0.0, 0.8]));
        for round in 0..400u32 {
            let o = V3::new(
                F::from_array(core::array::from_fn(|i| 3.0 * r(round, i as u32) - 1.5)),
                F::from_array(core::array::from_fn(|i| 3.0 * r(round, 16 + i as u32) - 1.5)),
                F::from_array(core::array::from_fn(|i| 3.0 * r(round, 32 + i as u32) - 1.5)),
            );
            let mut d = V3::new(
                F::from_array(core::array::from_fn(|i| 2.0 * r(round, 48 + i as u32) - 1.0)),
                F::from_array(core::array::from_fn(|i| 2.0 * r(round, 64 + i as u32) - 1.0)),
                F::from_array(core::array::from_fn(|i| 2.0 * r(round, 80 + i as u32) - 1.0)),
            );
            if round % 7 == 0 {
                // Axis-parallel, zero, denormal and non-finite directions.
                d.x = F::from_array([
                    0.0,
                    1e-40,
                    0.0,
                    f32::NAN,
                    0.0,
                    -1.0,
                    0.0,
                    0.5,
                    0.0,
                    0.0,
                    1.0,
                    -0.0,
                    0.0,
                    0.0,
                    2.0,
                    0.0,
                ]);
                d.y = F::splat(0.0);
            }
            let t_max = F::from_array(core::array::from_fn(|i| if i % 4 == 0 { 0.7 } else { f32::MAX }));
            let live = M::from_array(core::array::from_fn(|i| !(i + round as usize).is_multiple_of(9)));
            for any_hit in [false, true] {
                let h = cast(&tris, &[], o, d, t_max, live, any_hit);
                let (os, ds) = (lanes_of(o), lanes_of(d));
                for i in 0..LANES {
                    let want = if live.test(i) {
                        scalar(&tris, os[i], ds[i], t_max[i])
                    } else {
                        (NO_HIT, t_max[i], 0.0, 0.0, 0.0)
                    };
                    if any_hit {
                        assert_eq!(h.triangle[i] == NO_HIT, want.0 == NO_HIT, "round {round}, lane {i}");
                    } else {
                        let got = (h.triangle[i], h.t[i], h.u[i], h.v[i], h.w[i]);
                        assert_eq!(
                            [got.0, got.1.to_bits(), got.2.to_bits(), got.3.to_bits(), got.4.to_bits()],
                            [want.0, want.1.to_bits(), want.2.to_bits(), want.3.to_bits(), want.4.to_bits()],
                            "round {round}, lane {i}: {got:?} against {want:?}"
                        );
                    }
                }
            }
        }
    }
}
