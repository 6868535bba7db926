//! Sampling a triangle light by the solid angle it subtends (Arvo, "Stratified Sampling of
//! Spherical Triangles", SIGGRAPH 1995; the solid angle by Van Oosterom & Strackee, "The Solid
//! Angle of a Plane Triangle", IEEE Trans. Biomed. Eng. 1983; pbrt-v4 §6.5.4).
//!
//! Sampling a light uniformly by area gives next-event estimation a weight of cos θ_l·A / r²,
//! which grows without bound where a surface comes close to the light: a wall beside a lamp,
//! the ceiling around it. Those vertices are common in indirect paths, and their rare large
//! contributions are much of a closed room's noise. Sampled uniformly in solid angle the weight
//! is the solid angle Ω itself, bounded by 2π.
//!
//! Where the triangle is far away for its size (`NEAR`) or subtends less than `MIN_SOLID_ANGLE`,
//! cos θ_l / r² hardly varies over it, area sampling is as good and the warp's square roots and
//! divisions are saved (below `MIN_SOLID_ANGLE` it would also lose precision in single floats);
//! where it subtends more than `MAX_SOLID_ANGLE` (a point almost in its plane, facing it) the
//! spherical triangle degenerates. There the light is sampled by area. `SphericalTriangle::toward`
//! decides from the point and the triangle alone, so the light's density for multiple importance
//! sampling is the same whether its direction came from the light or from the BSDF.
//!
//! Only exactly rounded operations and `trig`'s polynomials, so both devices draw the same
//! directions; no sum adds a constant to a product of others that a driver could regroup.
use crate::glam::Vec3;
use crate::trig::{atan2, sincos_turns};
use crate::vecmath::{cross, dot, length, normalize};
#[allow(unused_imports)]
use spirv_std::num_traits::Float;

/// Below this solid angle (steradians) a triangle is sampled by area (pbrt-v4's bound).
pub const MIN_SOLID_ANGLE: f32 = 3e-4;
/// Above this a triangle is sampled by area: a point next to its plane.
pub const MAX_SOLID_ANGLE: f32 = 6.22;
/// Area over squared distance to the centroid at or below which a light is sampled by area
/// without computing its solid angle: there it subtends less than about this, and the
/// solid-angle warp, which costs several square roots and divisions, gains next to nothing.
pub const NEAR: f32 = 0.02;
pub const PLANE: f32 = 4.0;

/// A light triangle seen from a point, where it is sampled by solid angle: the unit vectors to
/// its corners and the solid angle Ω they span.
#[derive(Clone, Copy)]
pub struct SphericalTriangle {
    a: Vec3,
    b: Vec3,
    c: Vec3,
    pub omega: f32,
}

impl SphericalTriangle {
    /// Triangle (v0, v1, v2) of area `area` seen from `x`, or `None` where it is sampled by area:
    /// it subtends little (`NEAR`, `MIN_SOLID_ANGLE`) or almost a hemisphere (`MAX_SOLID_ANGLE`).
    /// Decided from the point and the triangle alone, so that the light's density is the same
    /// whether a direction came from the light or from the BSDF.
    #[inline]
    pub fn toward(x: Vec3, v0: Vec3, v1: Vec3, v2: Vec3, n: Vec3, area: f32) -> Option<Self> {
        // |v0 + v1 + v2 − 3x|² is nine times the squared distance to the centroid.
        let d = (v0 + v1 + v2) - x * 3.0;
        if !(area * 9.0 > NEAR * dot(d, d)) {
            return None;
        }
        let h = dot(n, v0 - x);
        if !(h * h < PLANE * area) {
            return None;
        }
        let (a, b, c) = (normalize(v0 - x), normalize(v1 - x), normalize(v2 - x));
        // tan(Ω/2) = |a·(b × c)| / (1 + a·b + b·c + c·a) for unit a, b, c: the precision of
        // small solid angles, which a sum of three corner angles less π would lose. The
        // constant is added last, to a sum of products alone.
        let num = dot(a, cross(b, c)).abs();
        let den = (dot(a, b) + dot(b, c) + dot(c, a)) + 1.0;
        let omega = 2.0 * atan2(num, den);
        // Not `RangeInclusive::contains`: rust-gpu emits a load through a pointer to the
        // range that spirv-val rejects.
        #[allow(clippy::manual_range_contains)]
        let inside = (omega >= MIN_SOLID_ANGLE) & (omega <= MAX_SOLID_ANGLE);
        if inside {
            Some(SphericalTriangle { a, b, c, omega })
        } else {
            None
        }
    }

    /// A unit direction uniform over the solid angle, for uniforms `u0`, `u1` in [0, 1): `u0`
    /// picks the area of the sub-triangle at corner a, `u1` the point along its far edge (Arvo
    /// §2). `None` where the spherical triangle is degenerate (a corner angle without a sine).
    #[inline]
    pub fn sample(&self, u0: f32, u1: f32) -> Option<Vec3> {
        let (a, b, c) = (self.a, self.b, self.c);
        let (ab, ca) = (cross(a, b), cross(c, a));
        let (lab, lca) = (length(ab), length(ca));
        if !((lab > 0.0) & (lca > 0.0)) {
            return None;
        }
        // The angle α at corner a, between the great circles a–b and a–c.
        let cos_alpha = (-dot(ab, ca) / (lab * lca)).clamp(-1.0, 1.0);
        let sin_alpha = (1.0 - cos_alpha * cos_alpha).max(0.0).sqrt();
        if !(sin_alpha > 0.0) {
            return None;
        }
        // The sub-triangle's area Â = u0·Ω; s, t = sin, cos of Â.
        let (s, t) = sincos_turns(u0 * (self.omega * (0.5 * core::f32::consts::FRAC_1_PI)));
        // φ = Â + π − α, the sub-triangle's angle sum less α: sin(Â + π) = −s, cos(Â + π) = −t.
        let sin_phi = t * sin_alpha - s * cos_alpha;
        let cos_phi = -(t * cos_alpha + s * sin_alpha);
        let k1 = cos_phi + cos_alpha;
        let k2 = sin_phi - sin_alpha * dot(a, b);
        // The cosine of the arc from a to the sub-triangle's third corner c′ on the arc a–c.
        let den = (k2 * sin_phi + k1 * cos_phi) * sin_alpha;
        let cos_b =
            if den != 0.0 { ((k2 + (k2 * cos_phi - k1 * sin_phi) * cos_alpha) / den).clamp(-1.0, 1.0) } else { 1.0 };
        let sin_b = (1.0 - cos_b * cos_b).max(0.0).sqrt();
        let c_perp = c - a * dot(c, a);
        let lc = length(c_perp);
        if !(lc > 0.0) {
            return None;
        }
        let c_prime = a * cos_b + c_perp * (sin_b / lc);
        // Along the arc from b to c′, uniformly in the cosine of the angle to b.
        let cos_theta = 1.0 - u1 * (1.0 - dot(c_prime, b));
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let d = c_prime - b * dot(c_prime, b);
        let ld = length(d);
        if !(ld > 0.0) {
            return Some(b);
        }
        Some(b * cos_theta + d * (sin_theta / ld))
    }
}

/// Barycentric weights (b0, b1, b2) of the point where the ray from `p` along `w` meets the
/// plane of (v0, v1, v2), clamped into the triangle; `None` where the ray runs along the plane or
/// away from it.
#[inline]
pub fn plane_weights(p: Vec3, w: Vec3, v0: Vec3, v1: Vec3, v2: Vec3) -> Option<(f32, f32, f32)> {
    let (e1, e2) = (v1 - v0, v2 - v0);
    let n = cross(e1, e2);
    let dn = dot(w, n);
    let t = dot(v0 - p, n) / dn;
    if !((dn != 0.0) & (t > 0.0)) {
        return None;
    }
    let q = (p - v0) + w * t;
    let inv = 1.0 / dot(n, n);
    // Rounding may put the point a hair outside: clamp it onto the triangle.
    let b1 = (dot(cross(q, e2), n) * inv).max(0.0);
    let b2 = (dot(cross(e1, q), n) * inv).max(0.0);
    let s = b1 + b2;
    let (b1, b2) = if s > 1.0 { (b1 / s, b2 / s) } else { (b1, b2) };
    // b0 = 1 − b1 − b2 written as one subtraction of a sum: no driver regrouping of a constant.
    let b0 = 1.0 - (b1 + b2);
    Some((b0, b1, b2))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn omega(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> f32 {
        SphericalTriangle::toward(p, a, b, c, normalize(cross(b - a, c - a)), 1e30).map_or(0.0, |s| s.omega)
    }

    #[test]
    fn solid_angle_of_a_cube_face_is_a_sixth_of_the_sphere() {
        // Two triangles make one face of a cube around the point: 4π/6 between them, in
        // either winding, and the same for a cube a thousand times smaller far from the origin.
        for (scale, at) in [(1.0f32, Vec3::ZERO), (1e-3, Vec3::new(2.0, -0.5, 0.7))] {
            let v = |x: f32, y: f32| at + Vec3::new(x, y, 1.0) * scale;
            let (a, b, c, d) = (v(-1.0, -1.0), v(1.0, -1.0), v(1.0, 1.0), v(-1.0, 1.0));
            let want = 4.0 * core::f32::consts::PI / 6.0;
            for got in [omega(at, a, b, c) + omega(at, a, c, d), omega(at, c, b, a) + omega(at, d, c, a)] {
                assert!((got - want).abs() < 2e-3 * want, "scale {scale}: {got} against {want}");
            }
        }
    }

    #[test]
    fn far_small_and_edge_on_triangles_are_sampled_by_area() {
        let (a, b, c) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0));
        let area = 0.5;
        // A/d² = 0.5 / 100 < NEAR: by area, without computing Ω.
        assert!(SphericalTriangle::toward(Vec3::new(0.3, 0.3, 10.0), a, b, c, Vec3::Z, area).is_none());
        // Close: by solid angle, 0.4318860 sr (the same formula in f64).
        let near = SphericalTriangle::toward(Vec3::new(0.3, 0.3, 1.0), a, b, c, Vec3::Z, area).unwrap();
        assert!((near.omega - 0.431_886).abs() < 1e-5, "{}", near.omega);
        // In the plane, beside the triangle: no solid angle, by area.
        assert!(SphericalTriangle::toward(Vec3::new(1.0, 1.0, 0.0), a, b, c, Vec3::Z, area).is_none());
        // Just above its middle: almost a hemisphere, beyond MAX_SOLID_ANGLE.
        assert!(SphericalTriangle::toward(Vec3::new(0.3, 0.3, 1e-4), a, b, c, Vec3::Z, area).is_none());
    }

    #[test]
    fn samples_land_on_the_triangle() {
        let p = Vec3::new(0.1, -0.3, 0.2);
        let (a, b, c) = (Vec3::new(-0.5, 1.0, -0.4), Vec3::new(0.7, 1.2, 0.1), Vec3::new(0.0, 0.9, 0.8));
        let st = SphericalTriangle::toward(p, a, b, c, normalize(cross(b - a, c - a)), 1.0).unwrap();
        let n = cross(b - a, c - a);
        for i in 0..4096 {
            let (u0, u1) = ((i % 64) as f32 / 64.0 + 1.0 / 128.0, (i / 64) as f32 / 64.0 + 1.0 / 128.0);
            let w = st.sample(u0, u1).unwrap();
            assert!((length(w) - 1.0).abs() < 1e-5);
            // Unclamped barycentrics of where the ray meets the plane: inside up to rounding.
            let t = dot(a - p, n) / dot(w, n);
            let q = p + w * t - a;
            let nn = dot(n, n);
            let (b1, b2) = (dot(cross(q, c - a), n) / nn, dot(cross(b - a, q), n) / nn);
            assert!(t > 0.0 && b1 > -1e-5 && b2 > -1e-5 && b1 + b2 < 1.0 + 1e-5, "u {u0} {u1}: {b1} {b2}");
            let (w0, w1, w2) = plane_weights(p, w, a, b, c).unwrap();
            assert!(w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0 && (w0 + w1 + w2 - 1.0).abs() < 1e-6);
        }
    }
}
