//! Watertight ray/triangle intersection (Woop, Benthin & Wald, "Watertight Ray/Triangle
//! Intersection", JCGT 2013).
//!
//! The ray is sheared and scaled so that it runs along +z from the origin; the triangle is tested
//! in 2D with edge functions. An edge shared by two triangles is evaluated from the same products
//! in both (negated), so a ray can never pass between them. A zero edge function counts as inside
//! for both neighbours: rays through edges and vertices hit at least one triangle.
//! No f64 fallback: not every GPU has `Float64`, and the zero case is already closed.
use crate::glam::Vec3;
use crate::layout::Triangle;
#[cfg(not(target_arch = "spirv"))]
use crate::layout::{TriBlock, BLOCK_WIDTH};
use crate::numerics::gamma;
use crate::vecmath::{axis, xyz};

/// Per-ray constants of the watertight test.
#[derive(Clone, Copy)]
pub struct RayShear {
    pub origin: Vec3,
    /// The origin's components in the order kx, ky, kz (for the CPU's block test).
    #[cfg_attr(target_arch = "spirv", allow(dead_code))]
    origin_k: Vec3,
    kx: u32,
    ky: u32,
    kz: u32,
    sx: f32,
    sy: f32,
    sz: f32,
}

/// A hit: distance along the (possibly unnormalised) direction and the unnormalised barycentric
/// weights of v0, v1, v2 (divide by their sum).
#[derive(Clone, Copy)]
pub struct TriangleHit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
    pub w: f32,
}

impl RayShear {
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        let a = dir.abs();
        // The dominant axis becomes z; ties keep the lowest index so both devices pick the same.
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = if kz == 2 { 0 } else { kz + 1 };
        let mut ky = if kx == 2 { 0 } else { kx + 1 };
        // Keep the winding of the projected triangle when the dominant component is negative.
        if axis(dir, kz) < 0.0 {
            core::mem::swap(&mut kx, &mut ky);
        }
        let dz = axis(dir, kz);
        let sz = 1.0 / dz;
        let origin_k = Vec3::new(axis(origin, kx), axis(origin, ky), axis(origin, kz));
        Self { origin, origin_k, kx, ky, kz, sx: axis(dir, kx) * sz, sy: axis(dir, ky) * sz, sz }
    }

    /// Intersects `tri`; returns the hit when its distance lies strictly inside (t_min, t_max).
    #[inline]
    pub fn intersect(&self, tri: &Triangle, t_min: f32, t_max: f32) -> Option<TriangleHit> {
        let a = xyz(tri.v0) - self.origin;
        let b = xyz(tri.v1) - self.origin;
        let c = xyz(tri.v2) - self.origin;
        let (akz, bkz, ckz) = (axis(a, self.kz), axis(b, self.kz), axis(c, self.kz));
        let ax = axis(a, self.kx) - self.sx * akz;
        let ay = axis(a, self.ky) - self.sy * akz;
        let bx = axis(b, self.kx) - self.sx * bkz;
        let by = axis(b, self.ky) - self.sy * bkz;
        let cx = axis(c, self.kx) - self.sx * ckz;
        let cy = axis(c, self.ky) - self.sy * ckz;
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        // Non-short-circuit `|`/`&`: one branch on the GPU instead of a cascade.
        let any_neg = (u < 0.0) | (v < 0.0) | (w < 0.0);
        let any_pos = (u > 0.0) | (v > 0.0) | (w > 0.0);
        if any_neg & any_pos {
            return None;
        }
        let det = u + v + w;
        if det == 0.0 {
            return None;
        }
        let t_scaled = u * (self.sz * akz) + v * (self.sz * bkz) + w * (self.sz * ckz);
        let t = t_scaled / det;
        // NaN (from a garbage ray) fails both comparisons and is rejected.
        if (t > t_min) & (t < t_max) {
            Some(TriangleHit { t, u, v, w })
        } else {
            None
        }
    }
}

/// One SIMD register of the CPU's leaf test: a lane per triangle of a `TriBlock`.
#[cfg(not(target_arch = "spirv"))]
type Lanes = core::simd::Simd<f32, { BLOCK_WIDTH as usize }>;

/// One vertex of a block's triangles in the sheared frame: (x, y) after the shear and the
/// distance coordinate before scaling, lane by lane the same operations as `RayShear::intersect`.
#[cfg(not(target_arch = "spirv"))]
#[inline]
fn sheared_lanes(
    b: &TriBlock,
    j: usize,
    k: (usize, usize, usize),
    o: (Lanes, Lanes, Lanes),
    s: (Lanes, Lanes),
) -> (Lanes, Lanes, Lanes) {
    let kz = Lanes::from_array(b.v[3 * j + k.2]) - o.2;
    let x = (Lanes::from_array(b.v[3 * j + k.0]) - o.0) - s.0 * kz;
    let y = (Lanes::from_array(b.v[3 * j + k.1]) - o.1) - s.1 * kz;
    (x, y, kz)
}

#[cfg(not(target_arch = "spirv"))]
impl RayShear {
    /// `intersect` on the `BLOCK_WIDTH` triangles of `b` at once, one per SIMD lane, considering
    /// only the lanes set in the bitmask `lanes`. Returns the lane with the smallest distance in
    /// (t_min, t_max), the lowest such lane on a tie, and its hit: exactly what testing the
    /// lanes one after another with `intersect`, narrowing t_max, returns, since every lane
    /// performs `intersect`'s operations in its order (IEEE single precision, no fused ops:
    /// `core::simd` never contracts a multiply and an add).
    /// With `first`, the lowest lane that hits (what a one-by-one any-hit test stops at).
    #[inline]
    pub fn intersect_block(
        &self,
        b: &TriBlock,
        lanes: u32,
        t_min: f32,
        t_max: f32,
        first: bool,
    ) -> Option<(u32, TriangleHit)> {
        use core::simd::cmp::{SimdPartialEq, SimdPartialOrd};
        // The axes are below 3 by construction; saying so lets the compiler drop the bounds
        // checks of the nine loads.
        let k = ((self.kx as usize).min(2), (self.ky as usize).min(2), (self.kz as usize).min(2));
        let o = (Lanes::splat(self.origin_k.x), Lanes::splat(self.origin_k.y), Lanes::splat(self.origin_k.z));
        let s = (Lanes::splat(self.sx), Lanes::splat(self.sy));
        let (ax, ay, akz) = sheared_lanes(b, 0, k, o, s);
        let (bx, by, bkz) = sheared_lanes(b, 1, k, o, s);
        let (cx, cy, ckz) = sheared_lanes(b, 2, k, o, s);
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        let zero = Lanes::splat(0.0);
        let any_neg = u.simd_lt(zero) | v.simd_lt(zero) | w.simd_lt(zero);
        let any_pos = u.simd_gt(zero) | v.simd_gt(zero) | w.simd_gt(zero);
        let det = u + v + w;
        // Most blocks a ray tests hold no triangle it passes through: leave before the division.
        let inside = (!(any_neg & any_pos) & det.simd_ne(zero)).to_bitmask() as u32 & lanes;
        if inside == 0 {
            return None;
        }
        let sz = Lanes::splat(self.sz);
        let t_scaled = u * (sz * akz) + v * (sz * bkz) + w * (sz * ckz);
        let t = t_scaled / det;
        let mask = (t.simd_gt(Lanes::splat(t_min)) & t.simd_lt(Lanes::splat(t_max))).to_bitmask() as u32 & inside;
        if mask == 0 {
            return None;
        }
        let ts = t.to_array();
        let mut lane = mask.trailing_zeros();
        if !first {
            // The other hitting lanes, lowest first; a later lane wins only when strictly closer.
            let mut rest = mask & (mask - 1);
            while rest != 0 {
                let l = rest.trailing_zeros();
                if ts[l as usize] < ts[lane as usize] {
                    lane = l;
                }
                rest &= rest - 1;
            }
        }
        let i = lane as usize;
        Some((lane, TriangleHit { t: ts[i], u: u.to_array()[i], v: v.to_array()[i], w: w.to_array()[i] }))
    }
}

/// Geometric normal (v1 − v0) × (v2 − v0), unnormalised. It points to the front side: the side
/// from which v0, v1, v2 appear counter-clockwise.
#[inline]
pub fn geometric_normal(tri: &Triangle) -> Vec3 {
    crate::vecmath::cross(xyz(tri.v1) - xyz(tri.v0), xyz(tri.v2) - xyz(tri.v0))
}

/// The geometric normal of the triangle's edges scaled by the power of two `s` that brings the
/// longest edge component into [1, 2), and `1 / s`. Scaling by a power of two is exact, so the
/// result is `s²` times `geometric_normal` bit for bit wherever that is representable, but its
/// length, squared, neither overflows (edges beyond 1e10 square to beyond f32's range twice) nor
/// underflows (edges below 1e-10); `numerics::inverse_power_of_two` has the scale.
#[inline]
fn scaled_normal(tri: &Triangle) -> (Vec3, f32) {
    let (e1, e2) = (xyz(tri.v1) - xyz(tri.v0), xyz(tri.v2) - xyz(tri.v0));
    let m = e1.abs().max(e2.abs());
    let s = crate::numerics::inverse_power_of_two(m.x.max(m.y).max(m.z));
    (crate::vecmath::cross(e1 * s, e2 * s), 1.0 / s)
}

/// The unit geometric normal, normalize((v1 − v0) × (v2 − v0)), computed without overflow or
/// underflow at any scale (`scaled_normal`; the same bits as the plain formula wherever that one
/// does not overflow): what `Triangle::with_unit_normal` stores in the `w` components.
#[inline]
pub fn unit_normal(tri: &Triangle) -> Vec3 {
    crate::vecmath::normalize(scaled_normal(tri).0)
}

/// The triangle's area, |(v1 − v0) × (v2 − v0)| / 2, at any scale (`scaled_normal`); zero only
/// for a triangle whose edges are parallel (or of zero length).
#[inline]
pub fn area(tri: &Triangle) -> f32 {
    let (n, inv_s) = scaled_normal(tri);
    0.5 * (crate::vecmath::length(n) * (inv_s * inv_s))
}

/// The unit normal stored in the `w` components (`unit_normal`'s value, bit for bit).
#[inline]
pub fn stored_normal(tri: &Triangle) -> Vec3 {
    Vec3::new(tri.v0.w, tri.v1.w, tri.v2.w)
}

impl Triangle {
    /// This triangle with its unit normal in the `w` components.
    #[inline]
    pub fn with_unit_normal(self) -> Self {
        let n = unit_normal(&self);
        Self { v0: xyz(self.v0).extend(n.x), v1: xyz(self.v1).extend(n.y), v2: xyz(self.v2).extend(n.z) }
    }
}

/// A point on a triangle and the bound of its rounding error, per axis (pbrt-v4 §6.8.5).
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    pub p: Vec3,
    pub error: Vec3,
}

/// The point with barycentric weights (b0, b1, b2) (summing to one): b0·v0 + b1·v1 + b2·v2, with
/// pbrt-v4's bound γ(7)·(|b0·v0| + |b1·v1| + |b2·v2|) (§6.8.5) taken at its largest axis for all
/// three: the watertight test measures distances in a sheared frame that mixes the axes, so a
/// triangle lying in a coordinate plane (a floor at y = 0, whose points are exact in y) still
/// needs its spawned rays lifted off it. Interpolating keeps the point on the triangle far more
/// accurately than `origin + t·dir`, and the bound scales with the coordinates: tiny scenes get
/// tiny offsets, scenes far from the origin large ones.
#[inline]
pub fn interpolate(tri: &Triangle, b0: f32, b1: f32, b2: f32) -> SurfacePoint {
    let (a, b, c) = (xyz(tri.v0) * b0, xyz(tri.v1) * b1, xyz(tri.v2) * b2);
    let sum = a.abs() + b.abs() + c.abs();
    let largest = if sum.x > sum.y { sum.x } else { sum.y };
    let largest = if sum.z > largest { sum.z } else { largest };
    SurfacePoint { p: a + b + c, error: Vec3::splat(largest * gamma(7)) }
}

/// The hit point of a watertight-test hit, from its barycentric weights.
#[inline]
pub fn hit_point(tri: &Triangle, hit: &TriangleHit) -> SurfacePoint {
    let inv = 1.0 / (hit.u + hit.v + hit.w);
    interpolate(tri, hit.u * inv, hit.v * inv, hit.w * inv)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::glam::Vec4;

    fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Triangle {
        Triangle {
            v0: Vec4::new(a[0], a[1], a[2], 0.0),
            v1: Vec4::new(b[0], b[1], b[2], 0.0),
            v2: Vec4::new(c[0], c[1], c[2], 0.0),
        }
    }

    #[test]
    fn hits_front_and_back_with_the_right_distance() {
        let t = tri([-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]);
        for &(oz, dz) in &[(2.0f32, -1.0f32), (-3.0, 1.0), (2.0, -0.5)] {
            let r = RayShear::new(Vec3::new(0.1, 0.0, oz), Vec3::new(0.0, 0.0, dz));
            let h = r.intersect(&t, 0.0, f32::INFINITY).expect("hit");
            assert!((h.t * dz.abs() - oz.abs()).abs() < 1e-6);
            let p = hit_point(&t, &h).p;
            assert!((p - Vec3::new(0.1, 0.0, 0.0)).abs().max_element() < 1e-6);
        }
        let r = RayShear::new(Vec3::new(2.0, 0.0, 1.0), Vec3::new(0.0, 0.0, -1.0));
        assert!(r.intersect(&t, 0.0, f32::INFINITY).is_none());
        let r = RayShear::new(Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, -1.0));
        assert!(r.intersect(&t, 0.0, 0.5).is_none(), "t_max respected");
    }

    #[test]
    fn shared_edge_has_no_gap() {
        // Two triangles sharing the diagonal of a unit square; rays on and near the diagonal.
        let a = tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]);
        let b = tri([0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]);
        for i in 0..=1000 {
            let s = i as f32 / 1000.0;
            for &e in &[0.0f32, 1e-7, -1e-7] {
                let o = Vec3::new(s + e, s, 1.0);
                let r = RayShear::new(o, Vec3::new(0.013, -0.007, -1.0));
                let hit = r.intersect(&a, 0.0, f32::INFINITY).is_some() | r.intersect(&b, 0.0, f32::INFINITY).is_some();
                let inside = (o.x + 0.013 >= 0.0) & (o.x + 0.013 <= 1.0) & (o.y - 0.007 >= 0.0) & (o.y - 0.007 <= 1.0);
                if inside && (0.001..0.98).contains(&s) {
                    assert!(hit, "gap at s={s} e={e}");
                }
            }
        }
    }

    /// `intersect_block` against `intersect` lane by lane: random and adversarial triangles
    /// (shared edges, duplicates for exact ties, degenerate ones, the zero lane), every lane mask
    /// of the low four lanes and of the high four with a random rest, both selection rules; the
    /// hit must be bit for bit the one-by-one test's.
    #[test]
    fn block_lanes_equal_one_by_one() {
        const W: usize = BLOCK_WIDTH as usize;
        let mut state = 0x2545_f491u32;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            (state >> 8) as f32 / 16_777_216.0
        };
        let mut checked = 0;
        for case in 0..4000 {
            let mut r = || next() * 2.0 - 1.0;
            let base = tri([r(), r(), r()], [r(), r(), r()], [r(), r(), r()]);
            let mut lanes = [base; W];
            for (l, lane) in lanes.iter_mut().enumerate() {
                *lane = match (case + l) % 5 {
                    0 => base,
                    1 => tri([r(), r(), r()], [r(), r(), r()], [r(), r(), r()]),
                    // Shares an edge with `base`.
                    2 => Triangle { v0: base.v1, v1: base.v0, v2: tri([r(), r(), r()], [0.0; 3], [0.0; 3]).v0 },
                    3 => tri([0.0; 3], [0.0; 3], [0.0; 3]), // degenerate
                    _ => tri([r(), r(), 0.25], [r(), r(), 0.25], [r(), r(), 0.25]), // axis-aligned
                };
            }
            if case % 2 == 0 {
                lanes[(case / 2) % W] = lanes[(case / 8 + 1) % W]; // an exact tie, or a repeat
            }
            let mut block = TriBlock::default();
            for (l, t) in lanes.iter().enumerate() {
                block.set_lane(l, t);
            }
            let o = Vec3::new(r() * 3.0, r() * 3.0, r() * 3.0);
            let target = Vec3::new(r() * 0.5, r() * 0.5, r() * 0.5);
            let mut d = target - o;
            if case % 7 == 0 {
                d = Vec3::new(0.0, 0.0, if o.z > 0.0 { -1.0 } else { 1.0 }); // axis-parallel
            }
            let shear = RayShear::new(o, d);
            let t_max = if case % 3 == 0 { f32::INFINITY } else { next() * 4.0 };
            let rest = (next() * 256.0) as u32 & 0xff;
            let masks = (0..16u32).map(|m| m | (rest & !0xf)).chain((0..16u32).map(|m| (m << 4) | (rest & 0xf)));
            for mask in masks {
                for first in [false, true] {
                    let mut want: Option<(u32, TriangleHit)> = None;
                    for l in 0..W as u32 {
                        if (mask >> l) & 1 == 0 || (first && want.is_some()) {
                            continue;
                        }
                        let limit = want.map_or(t_max, |(_, h)| h.t);
                        if let Some(h) = shear.intersect(&lanes[l as usize], 0.0, limit) {
                            want = Some((l, h));
                        }
                    }
                    let got = shear.intersect_block(&block, mask, 0.0, t_max, first);
                    let key = |x: Option<(u32, TriangleHit)>| {
                        x.map(|(l, h)| (l, h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.w.to_bits()))
                    };
                    assert_eq!(key(got), key(want), "case {case} mask {mask:08b} first {first}");
                    checked += want.is_some() as u32;
                }
            }
        }
        assert!(checked > 10_000, "too few hits to mean anything: {checked}");
    }

    #[test]
    fn normal_points_to_the_ccw_side() {
        let t = tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        assert!(geometric_normal(&t).z > 0.0);
    }
}
