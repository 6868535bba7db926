//! The scalar integrator's per-sample arithmetic, lane by lane: each function here is the one
//! named in its doc, computed with the same operations in the same order for each lane, so it
//! returns the same bits (the tests compare them on many inputs).
use super::{sqrt, F, M, U, V3};
use crate::layout::RenderParams;
use crate::numerics::gamma;
use crate::vecmath::xyz;
use core::simd::cmp::{SimdPartialEq, SimdPartialOrd};
use core::simd::num::SimdFloat;
use core::simd::Select;

/// `camera::primary_direction` at film positions (x, y).
#[inline(always)]
pub fn primary_direction(p: &RenderParams, x: F, y: F) -> V3 {
    let sx = F::splat(2.0) * x * F::splat(p.inv_width) - F::splat(1.0);
    let sy = F::splat(1.0) - F::splat(2.0) * y * F::splat(p.inv_height);
    (V3::splat(xyz(p.forward)) + V3::splat(xyz(p.right)).scale(sx) + V3::splat(xyz(p.up)).scale(sy)).normalize()
}

/// `trig::sin_quarter`.
#[inline(always)]
fn sin_quarter(x: F) -> F {
    let c = F::splat;
    let x2 = x * x;
    x * (c(1.0) + x2 * (c(-1.0 / 6.0) + x2 * (c(1.0 / 120.0) + x2 * (c(-1.0 / 5040.0) + x2 * c(1.0 / 362880.0)))))
}

/// `trig::cos_quarter`.
#[inline(always)]
fn cos_quarter(x: F) -> F {
    let c = F::splat;
    let x2 = x * x;
    c(1.0)
        + x2 * (c(-0.5)
            + x2 * (c(1.0 / 24.0) + x2 * (c(-1.0 / 720.0) + x2 * (c(1.0 / 40320.0) + x2 * c(-1.0 / 3628800.0)))))
}

/// `sampling::cosine_hemisphere` (through `concentric_disk`): both of the disk's branches
/// are the same operations on swapped inputs, so one evaluation serves either.
#[inline(always)]
pub fn cosine_hemisphere(u1: F, u2: F) -> V3 {
    let (one, zero) = (F::splat(1.0), F::splat(0.0));
    let a = F::splat(2.0) * u1 - one;
    let b = F::splat(2.0) * u2 - one;
    let centre = a.simd_eq(zero) & b.simd_eq(zero);
    let wide = a.abs().simd_gt(b.abs());
    let (num, den) = (wide.select(b, a), wide.select(a, b));
    let phi = F::splat(core::f32::consts::FRAC_PI_4) * (num / den);
    let (c, s) = (cos_quarter(phi), sin_quarter(phi));
    let x = centre.select(zero, den * wide.select(c, s));
    let y = centre.select(zero, den * wide.select(s, c));
    let z2 = one - x * x - y * y;
    V3::new(x, y, z2.simd_gt(zero).select(sqrt(z2), zero))
}

/// `sampling::orthonormal_basis`.
#[inline(always)]
pub fn orthonormal_basis(n: V3) -> (V3, V3) {
    let sign = n.z.simd_ge(F::splat(0.0)).select(F::splat(1.0), F::splat(-1.0));
    let a = F::splat(-1.0) / (sign + n.z);
    let b = n.x * n.y * a;
    (V3::new(F::splat(1.0) + sign * n.x * n.x * a, sign * b, -sign * n.x), V3::new(b, sign + n.y * n.y * a, -n.y))
}

/// `sampling::uniform_triangle`.
#[inline(always)]
pub fn uniform_triangle(u1: F, u2: F) -> (F, F, F) {
    let su = sqrt(u1);
    let b1 = u2 * su;
    (F::splat(1.0) - su, b1, su - b1)
}

/// `sampling::power_heuristic`.
#[inline(always)]
pub fn power_heuristic(f: F, g: F) -> F {
    let f2 = f * f;
    let g2 = g * g;
    let sum = f2 + g2;
    let w = f2.simd_gt(F::splat(f32::MAX)).select(F::splat(1.0), f2 / sum);
    sum.simd_eq(F::splat(0.0)).select(F::splat(0.0), w)
}

/// The power heuristic's weight of `f` among three strategies' densities.
#[inline(always)]
pub fn power_heuristic3(f: F, g: F, h: F) -> F {
    let f2 = f * f;
    let sum = f2 + g * g + h * h;
    let w = f2.simd_gt(F::splat(f32::MAX)).select(F::splat(1.0), f2 / sum);
    sum.simd_eq(F::splat(0.0)).select(F::splat(0.0), w)
}

/// `numerics::is_finite`.
#[inline(always)]
fn is_finite(x: F) -> M {
    (x.to_bits() & U::splat(0x7f80_0000)).simd_ne(U::splat(0x7f80_0000))
}

/// `numerics::next_float_up`.
#[inline(always)]
fn next_float_up(x: F) -> F {
    let zero = F::splat(0.0);
    let keep = !is_finite(x) & x.simd_gt(zero);
    let x0 = x.simd_eq(zero).select(zero, x);
    let bits = x0.to_bits();
    let bits = x0.simd_ge(zero).select(bits + U::splat(1), bits - U::splat(1));
    keep.select(x, F::from_bits(bits))
}

/// `numerics::next_float_down`.
#[inline(always)]
fn next_float_down(x: F) -> F {
    let zero = F::splat(0.0);
    let keep = !is_finite(x) & x.simd_lt(zero);
    let x0 = x.simd_eq(zero).select(F::splat(-0.0), x);
    let bits = x0.to_bits();
    let bits = x0.simd_gt(zero).select(bits - U::splat(1), bits + U::splat(1));
    keep.select(x, F::from_bits(bits))
}

/// `numerics::step_away`.
#[inline(always)]
fn step_away(x: F, direction: F) -> F {
    let zero = F::splat(0.0);
    direction.simd_gt(zero).select(next_float_up(x), direction.simd_lt(zero).select(next_float_down(x), x))
}

/// `numerics::offset_ray_origin` for an error bound that is the same on every axis (`error`,
/// as `interpolate` makes it).
#[inline(always)]
pub fn offset_ray_origin(p: V3, error: F, n: V3) -> V3 {
    let d = n.x.abs() * error + n.y.abs() * error + n.z.abs() * error;
    let offset = n.scale(d);
    V3::new(step_away(p.x + offset.x, n.x), step_away(p.y + offset.y, n.y), step_away(p.z + offset.z, n.z))
}

/// Sixteen triangles' vertices and stored unit normals (`layout::Triangle`).
#[derive(Clone, Copy)]
pub struct Triangles {
    pub v0: V3,
    pub v1: V3,
    pub v2: V3,
    pub n: V3,
}

impl Triangles {
    /// `triangle::geometric_normal`.
    #[inline(always)]
    pub fn geometric_normal(&self) -> V3 {
        (self.v1 - self.v0).cross(self.v2 - self.v0)
    }

    /// `triangle::interpolate`: the point and its error bound (the same on every axis).
    #[inline(always)]
    pub fn interpolate(&self, b0: F, b1: F, b2: F) -> (V3, F) {
        let (a, b, c) = (self.v0.scale(b0), self.v1.scale(b1), self.v2.scale(b2));
        let sx = a.x.abs() + b.x.abs() + c.x.abs();
        let sy = a.y.abs() + b.y.abs() + c.y.abs();
        let sz = a.z.abs() + b.z.abs() + c.z.abs();
        let largest = sx.simd_gt(sy).select(sx, sy);
        let largest = sz.simd_gt(largest).select(sz, largest);
        (a + b + c, largest * F::splat(gamma(7)))
    }
}

/// `surface::weights`: a hit's barycentric weights from its unnormalised ones, the weights
/// `triangle::hit_point` interpolates the hit point with.
#[inline(always)]
pub fn weights(u: F, v: F, w: F) -> (F, F, F) {
    let inv = F::splat(1.0) / (u + v + w);
    (u * inv, v * inv, w * inv)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::glam::{Vec3, Vec4};
    use crate::lanes::LANES;
    use crate::layout::Triangle;
    use crate::rng::pcg4d;

    /// Sixteen pseudo-random values from `key`, spread over [lo, hi).
    fn values(key: u32, lo: f32, hi: f32) -> F {
        F::from_array(core::array::from_fn(|i| {
            let h = pcg4d(key, i as u32, 0x77, 1)[0];
            lo + (hi - lo) * ((h >> 8) as f32 / 16_777_216.0)
        }))
    }

    fn same(a: F, b: [f32; LANES], what: &str) {
        for i in 0..LANES {
            assert_eq!(a[i].to_bits(), b[i].to_bits(), "{what}, lane {i}: {} against {}", a[i], b[i]);
        }
    }

    #[test]
    fn warps_match_the_scalar_ones() {
        for k in 0..200 {
            let (u1, u2) = (values(2 * k, 0.0, 1.0), values(2 * k + 1, 0.0, 1.0));
            // Hit the disk's centre and its diagonals exactly too.
            let u1 = if k == 0 { F::splat(0.5) } else { u1 };
            let u2 = if k < 2 {
                F::splat(0.5)
            } else if k == 2 {
                u1
            } else {
                u2
            };
            let h = cosine_hemisphere(u1, u2);
            let s: [Vec3; LANES] = core::array::from_fn(|i| crate::sampling::cosine_hemisphere(u1[i], u2[i]));
            same(h.x, s.map(|v| v.x), "cosine x");
            same(h.y, s.map(|v| v.y), "cosine y");
            same(h.z, s.map(|v| v.z), "cosine z");
            let t = uniform_triangle(u1, u2);
            let st: [(f32, f32, f32); LANES] =
                core::array::from_fn(|i| crate::sampling::uniform_triangle(u1[i], u2[i]));
            same(t.0, st.map(|v| v.0), "triangle b0");
            same(t.1, st.map(|v| v.1), "triangle b1");
            same(t.2, st.map(|v| v.2), "triangle b2");
            let (f, g) = (values(3 * k, 0.0, 4.0), values(3 * k + 7, 0.0, 4.0));
            let g = if k == 3 { F::splat(0.0) } else { g };
            let f = if k < 4 { F::splat(if k == 3 { 0.0 } else { f32::INFINITY }) } else { f };
            let w = power_heuristic(f, g);
            same(w, core::array::from_fn(|i| crate::sampling::power_heuristic(f[i], g[i])), "power heuristic");
            let n = V3::new(values(5 * k, -1.0, 1.0), values(5 * k + 1, -1.0, 1.0), values(5 * k + 2, -1.0, 1.0))
                .normalize();
            let (a, b) = orthonormal_basis(n);
            let sb: [(Vec3, Vec3); LANES] = core::array::from_fn(|i| crate::sampling::orthonormal_basis(n.lane(i)));
            same(a.x, sb.map(|v| v.0.x), "basis t.x");
            same(a.z, sb.map(|v| v.0.z), "basis t.z");
            same(b.y, sb.map(|v| v.1.y), "basis b.y");
        }
    }

    #[test]
    fn hit_points_and_offsets_match_the_scalar_ones() {
        for k in 0..200u32 {
            let scale = [1e-3f32, 1.0, 1e3, 3e5][(k % 4) as usize];
            let v = |j: u32| {
                V3::new(
                    values(k * 9 + j, -scale, scale),
                    values(k * 9 + j + 3, -scale, scale),
                    values(k * 9 + j + 6, 0.0, scale),
                )
            };
            let mut tris = Triangles { v0: v(0), v1: v(1), v2: v(2), n: V3::ZERO };
            if k % 5 == 0 {
                // A triangle in a coordinate plane: exact coordinates, zero normal components.
                tris.v0.y = F::splat(0.0);
                tris.v1.y = F::splat(0.0);
                tris.v2.y = F::splat(0.0);
            }
            let scalar: [Triangle; LANES] = core::array::from_fn(|i| Triangle {
                v0: Vec4::new(tris.v0.x[i], tris.v0.y[i], tris.v0.z[i], 0.0),
                v1: Vec4::new(tris.v1.x[i], tris.v1.y[i], tris.v1.z[i], 0.0),
                v2: Vec4::new(tris.v2.x[i], tris.v2.y[i], tris.v2.z[i], 0.0),
            });
            let ng = tris.geometric_normal();
            let sng: [Vec3; LANES] = core::array::from_fn(|i| crate::triangle::geometric_normal(&scalar[i]));
            same(ng.y, sng.map(|v| v.y), "geometric normal y");
            let (u, w, t) = (values(k, 0.0, 2.0), values(k + 1000, 0.0, 2.0), values(k + 2000, 0.0, 2.0));
            let b = weights(u, w, t);
            let (p, err) = tris.interpolate(b.0, b.1, b.2);
            let n = ng.normalize();
            let n = if k % 3 == 0 { -n } else { n };
            let spawn = offset_ray_origin(p, err, n);
            for i in 0..LANES {
                let hit = crate::triangle::TriangleHit { t: 1.0, u: u[i], v: w[i], w: t[i] };
                let sp = crate::triangle::hit_point(&scalar[i], &hit);
                assert_eq!(p.lane(i), sp.p, "hit point, lane {i}");
                assert_eq!(err[i], sp.error.x, "error, lane {i}");
                let so = crate::numerics::offset_ray_origin(sp.p, sp.error, n.lane(i));
                let lo = spawn.lane(i);
                assert_eq!(
                    [lo.x.to_bits(), lo.y.to_bits(), lo.z.to_bits()],
                    [so.x.to_bits(), so.y.to_bits(), so.z.to_bits()],
                    "offset, lane {i}"
                );
            }
        }
        // Zeros, infinities and NaN stepped as `next_float_up` and `next_float_down` step them.
        let x = F::from_array([
            0.0,
            -0.0,
            1.0,
            -1.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::MAX,
            -f32::MAX,
            1e-45,
            -1e-45,
            3.5,
            -7.25,
            0.1,
        ]);
        let up = next_float_up(x);
        let down = next_float_down(x);
        for i in 0..LANES {
            assert_eq!(up[i].to_bits(), crate::numerics::next_float_up(x[i]).to_bits(), "up {}", x[i]);
            assert_eq!(down[i].to_bits(), crate::numerics::next_float_down(x[i]).to_bits(), "down {}", x[i]);
        }
    }

    #[test]
    fn camera_directions_match() {
        let p = RenderParams {
            inv_width: 1.0 / 37.0,
            inv_height: 1.0 / 21.0,
            forward: Vec4::new(0.1, -0.2, -1.3, 0.0),
            right: Vec4::new(0.7, 0.0, 0.05, 0.0),
            up: Vec4::new(0.0, 0.4, -0.01, 0.0),
            ..RenderParams::default()
        };
        let (x, y) = (values(1, 0.0, 37.0), values(2, 0.0, 21.0));
        let d = primary_direction(&p, x, y);
        for i in 0..LANES {
            assert_eq!(d.lane(i), crate::camera::primary_direction(&p, x[i], y[i]), "lane {i}");
        }
    }
}
