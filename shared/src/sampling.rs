//! Sample warps and the multiple-importance weight (pbrt-v4 §A.5, Veach 1997 §9).
//!
//! Only exactly rounded operations and `trig`'s polynomials, so a warp gives the same bits on
//! every device for the same uniforms.
use crate::glam::Vec3;
use crate::layout::{Light, Triangle};
use crate::triangle::{interpolate, stored_normal, SurfacePoint};
use crate::trig::{cos_quarter, sin_quarter};
#[allow(unused_imports)]
use spirv_std::num_traits::Float;

pub const PI: f32 = core::f32::consts::PI;
pub const INV_PI: f32 = core::f32::consts::FRAC_1_PI;

/// Shirley & Chiu's concentric map of [0,1)² onto the unit disk (area preserving, low
/// distortion). The angle is always within ±π/4 of an axis, so quarter-range sin/cos suffice.
#[inline]
pub fn concentric_disk(u1: f32, u2: f32) -> (f32, f32) {
    let a = 2.0 * u1 - 1.0;
    let b = 2.0 * u2 - 1.0;
    if (a == 0.0) & (b == 0.0) {
        return (0.0, 0.0);
    }
    // Nearer the x axis: the angle φ = π/4 · b/a, the point a·(cos φ, sin φ). Nearer the y axis:
    // θ = π/2 − φ' with φ' = π/4 · a/b, so cos θ = sin φ' and sin θ = cos φ'. The two cases pick
    // their operands and one sine and one cosine serve both (a shader inlines each once).
    let wide = a.abs() > b.abs();
    let (r, num, den) = if wide { (a, b, a) } else { (b, a, b) };
    let phi = core::f32::consts::FRAC_PI_4 * (num / den);
    let (c, s) = (r * cos_quarter(phi), r * sin_quarter(phi));
    if wide {
        (c, s)
    } else {
        (s, c)
    }
}

/// Cosine-weighted direction about +z (Malley's method); pdf = cos θ / π.
#[inline]
pub fn cosine_hemisphere(u1: f32, u2: f32) -> Vec3 {
    cosine_hemisphere_at(concentric_disk(u1, u2))
}

/// `cosine_hemisphere` from the point (x, y) of the unit disk that `concentric_disk` gave.
#[inline]
pub fn cosine_hemisphere_at((x, y): (f32, f32)) -> Vec3 {
    let z2 = 1.0 - x * x - y * y;
    Vec3::new(x, y, if z2 > 0.0 { z2.sqrt() } else { 0.0 })
}

/// An orthonormal basis (t, b) around unit `n` (Duff et al., "Building an Orthonormal Basis,
/// Revisited", JCGT 2017): branch-free apart from the sign, no normalisation needed.
#[inline]
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), Vec3::new(b, sign + n.y * n.y * a, -n.y))
}

/// Uniform barycentric weights of (v0, v1, v2) on a triangle (pbrt-v3 `UniformSampleTriangle`).
/// b2 is written as `su − b1`, not `1 − b0 − b1`, which SPIR-V optimisers reassociate.
#[inline]
pub fn uniform_triangle(u1: f32, u2: f32) -> (f32, f32, f32) {
    let su = u1.sqrt();
    let b0 = 1.0 - su;
    let b1 = u2 * su;
    (b0, b1, su - b1)
}

/// A point on an emitting triangle, uniform by area: where it lies (with its rounding bound), its
/// barycentric weights (for an emission texture) and the triangle's stored normal, the side it
/// emits on (`surface::emitted`).
#[derive(Clone, Copy)]
pub struct LightPoint {
    pub at: SurfacePoint,
    pub b: (f32, f32, f32),
    pub n: Vec3,
}

/// The point that (`u1`, `u2`) pick on `tri` by `uniform_triangle`. Next-event estimation, the
/// light subpath's first vertex and the connection rule's probe all place their light points
/// here, so that the three see the same point for the same uniforms.
#[inline(always)]
pub fn light_point(tri: &Triangle, u1: f32, u2: f32) -> LightPoint {
    let (b0, b1, b2) = uniform_triangle(u1, u2);
    LightPoint { at: interpolate(tri, b0, b1, b2), b: (b0, b1, b2), n: stored_normal(tri) }
}

/// The power heuristic's weight of `f` among three strategies' densities `f`, `g`, `h`.
#[inline]
pub fn power_heuristic3(f: f32, g: f32, h: f32) -> f32 {
    let f2 = f * f;
    let sum = f2 + g * g + h * h;
    if sum == 0.0 {
        return 0.0;
    }
    if f2 > f32::MAX {
        return 1.0;
    }
    f2 / sum
}

/// Veach's power heuristic (β = 2) for the strategy with density `f` against one with `g`.
#[inline]
pub fn power_heuristic(f: f32, g: f32) -> f32 {
    let f2 = f * f;
    let g2 = g * g;
    if f2 + g2 == 0.0 {
        return 0.0;
    }
    // An infinite density (a delta) takes all the weight; ∞/∞ would be NaN.
    if f2 > f32::MAX {
        return 1.0;
    }
    f2 / (f2 + g2)
}

/// Index of the light whose cumulative interval contains `u` (binary search over `cdf`).
#[inline]
pub fn select_light(lights: &[Light], count: u32, u: f32) -> u32 {
    let mut lo = 0u32;
    let mut hi = count - 1;
    while lo < hi {
        let mid = (lo + hi) / 2;
        if u < lights[mid as usize].cdf {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo
}

/// `u` (which picked light `index` with `select_light`) rescaled to [0, 1) within that light's
/// interval of the cdf: a fresh uniform for sampling a point on the light, still stratified
/// together with the other dimensions of its set (pbrt-v4's `SampleDiscrete` remapping). The
/// picked light's interval is at least `u`'s resolution wide, so the result keeps 24 − log2(1/pmf)
/// bits: plenty for scenes whose lights do not each carry a vanishing share of the power.
#[inline]
pub fn remap_in_light(lights: &[Light], index: u32, u: f32) -> f32 {
    let lo = if index == 0 { 0.0 } else { lights[index as usize - 1].cdf };
    remap_between(lo, lights[index as usize].cdf, u)
}

/// The light that `u` picks and `u` rescaled within its interval, as next-event estimation and
/// the light subpath pick one: with several lights (`many`) by `select_light` and
/// `remap_in_light`; with one, light 0 and `u` itself (its interval is [0, 1]).
#[inline(always)]
pub fn pick_light(lights: &[Light], count: u32, many: bool, u: f32) -> (u32, f32) {
    if many {
        let index = select_light(lights, count, u);
        (index, remap_in_light(lights, index, u))
    } else {
        (0, u)
    }
}

/// `u`, which fell in a cdf's interval [lo, hi), rescaled to [0, 1).
#[inline]
pub fn remap_between(lo: f32, hi: f32, u: f32) -> f32 {
    let r = if hi > lo { (u - lo) / (hi - lo) } else { 0.0 };
    // Rounding may land exactly on 1 (or a hair below 0); keep the result in [0, 1).
    if r < 0.0 {
        0.0
    } else if r < ONE_MINUS_EPSILON {
        r
    } else {
        ONE_MINUS_EPSILON
    }
}

/// The largest f32 below 1.
pub const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disk_and_hemisphere_are_unit() {
        for i in 0..64 {
            for j in 0..64 {
                let (u1, u2) = (i as f32 / 64.0, j as f32 / 64.0);
                let (x, y) = concentric_disk(u1, u2);
                assert!(x * x + y * y <= 1.0 + 1e-6);
                let w = cosine_hemisphere(u1, u2);
                assert!((w.length() - 1.0).abs() < 1e-5 && w.z >= 0.0);
            }
        }
    }

    #[test]
    fn basis_is_orthonormal() {
        for &n in &[
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.5, 0.81).normalize(),
            Vec3::new(-1e-4, 1e-4, -1.0).normalize(),
        ] {
            let (t, b) = orthonormal_basis(n);
            assert!(t.dot(b).abs() < 1e-5 && t.dot(n).abs() < 1e-5 && b.dot(n).abs() < 1e-5);
            assert!((t.length() - 1.0).abs() < 1e-5 && (b.length() - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn triangle_weights_sum_to_one() {
        for i in 0..100 {
            let (b0, b1, b2) = uniform_triangle(i as f32 / 100.0, 0.37);
            assert!((b0 + b1 + b2 - 1.0).abs() < 1e-6 && b0 >= 0.0 && b1 >= 0.0 && b2 >= 0.0);
        }
    }

    #[test]
    fn light_selection_follows_the_cdf() {
        let l = |cdf| Light { triangle: 0, pmf: 0.0, cdf, area: 1.0 };
        let lights = [l(0.25), l(0.5), l(0.5), l(1.0)];
        assert_eq!(select_light(&lights, 4, 0.0), 0);
        assert_eq!(select_light(&lights, 4, 0.2499), 0);
        assert_eq!(select_light(&lights, 4, 0.25), 1);
        assert_eq!(select_light(&lights, 4, 0.5), 3, "zero-probability light 2 is never picked");
        assert_eq!(select_light(&lights, 4, 0.9999), 3);
        assert_eq!(select_light(&lights, 1, 0.7), 0);
    }

    #[test]
    fn remapped_uniform_spans_the_picked_interval() {
        let l = |pmf: f32, cdf: f32| Light { triangle: 0, pmf, cdf, area: 1.0 };
        let lights = [l(0.25, 0.25), l(0.0, 0.25), l(0.75, 1.0)];
        // The interval of light 2 is [0.25, 1): its ends map to 0 and just below 1, its middle
        // to the middle, and the result is always in [0, 1).
        assert_eq!(remap_in_light(&lights, 2, 0.25), 0.0);
        assert!((remap_in_light(&lights, 2, 0.625) - 0.5).abs() < 1e-6);
        assert!(remap_in_light(&lights, 2, ONE_MINUS_EPSILON) < 1.0);
        assert!((remap_in_light(&lights, 0, 0.125) - 0.5).abs() < 1e-6);
        // Monotone within an interval, so a stratified u stays stratified.
        let mut last = -1.0;
        for i in 0..1000 {
            let u = 0.25 + 0.75 * i as f32 / 1000.0;
            assert_eq!(select_light(&lights, 3, u), 2);
            let r = remap_in_light(&lights, 2, u);
            assert!(r >= last && (0.0..1.0).contains(&r), "u {u} -> {r}");
            last = r;
        }
        assert_eq!(remap_in_light(&lights, 1, 0.25), 0.0, "an empty interval maps to 0");
    }

    #[test]
    fn pick_light_is_the_search_and_the_remap() {
        let l = |pmf: f32, cdf: f32| Light { triangle: 0, pmf, cdf, area: 1.0 };
        let lights = [l(0.25, 0.25), l(0.0, 0.25), l(0.75, 1.0)];
        for u in [0.0, 0.1, 0.25, 0.4, 0.625, 0.99, ONE_MINUS_EPSILON] {
            let index = select_light(&lights, 3, u);
            assert_eq!(pick_light(&lights, 3, true, u), (index, remap_in_light(&lights, index, u)), "u {u}");
            // One light: light 0 and the uniform unchanged, the search skipped.
            assert_eq!(pick_light(&lights, 1, false, u), (0, u), "u {u}");
        }
        assert_eq!(pick_light(&lights, 3, true, 0.625), (2, 0.5));
    }

    #[test]
    fn power_heuristic_limits() {
        assert_eq!(power_heuristic(1.0, 0.0), 1.0);
        assert_eq!(power_heuristic(0.0, 0.0), 0.0);
        assert_eq!(power_heuristic(f32::INFINITY, 1.0), 1.0);
        assert!((power_heuristic(1.0, 1.0) - 0.5).abs() < 1e-7);
    }

    #[test]
    fn three_strategies_weights_sum_to_one() {
        let mut state = 0x1234_5678u32;
        for _ in 0..1000 {
            let mut next = || {
                state = state.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
                (state >> 8) as f32 / (1u32 << 24) as f32 * 10.0
            };
            let (f, g, h) = (next(), next(), next());
            let sum = power_heuristic3(f, g, h) + power_heuristic3(g, h, f) + power_heuristic3(h, f, g);
            assert!((sum - 1.0).abs() < 1e-5, "{f} {g} {h}: {sum}");
        }
        // With the third density zero it is the two-strategy heuristic, bit for bit.
        for (f, g) in [(1.0, 2.0), (0.3, 0.0), (1e-20, 3e-21), (7.0, 7.0)] {
            assert_eq!(power_heuristic3(f, g, 0.0).to_bits(), power_heuristic(f, g).to_bits(), "{f} {g}");
        }
        assert_eq!(power_heuristic3(0.0, 0.0, 0.0), 0.0);
        assert_eq!(power_heuristic3(f32::INFINITY, 1.0, 1.0), 1.0);
    }
}
