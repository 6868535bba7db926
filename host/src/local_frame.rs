//! Scene-relative coordinates: a scene far from the world origin (a building at survey
//! coordinates, a level tile at 1e5) is moved next to the origin before its tree is built, and
//! the camera with it, so rendering runs on small numbers.
//!
//! Why: every conservative bound in `shared::numerics` grows with the coordinates' magnitude, not
//! the scene's size (pbrt-v4 §6.8). At 1e5 the bound that lifts spawned rays off a surface is
//! about 0.04 units, 7% of a Cornell box, enough to shift contact shadows and corners visibly.
//! Production renderers render camera- or object-relative for the same reason.
//!
//! The move is exact, so the geometry is bit for bit the same shape: on each axis where the scene
//! lies wholly within a factor of two of one coordinate (min |x| ≥ max |x| / 2, one sign), every
//! coordinate's ulp is q or q/2 (q the ulp of the largest), the shift is a multiple of q, and each
//! difference is a multiple of q/2 no larger than max |x| / 2 < 2^24 · q/2: representable. Axes
//! that straddle or approach zero are left alone; they are not where precision is lost.
use crate::scene::Scene;
use shared::glam::Vec3;

/// The exact shift of one axis spanning `lo..=hi`, or 0 when the axis is not far from zero.
pub fn axis_shift(lo: f32, hi: f32) -> f32 {
    if !(lo.is_finite() && hi.is_finite()) || (lo < 0.0) != (hi < 0.0) {
        return 0.0;
    }
    let (near, far) = if lo.abs() <= hi.abs() { (lo.abs(), hi.abs()) } else { (hi.abs(), lo.abs()) };
    if near < far / 2.0 || far < f32::MIN_POSITIVE {
        return 0.0;
    }
    // The ulp of `far`: its exponent with a one-bit mantissa, times 2^-23.
    let q = f32::from_bits(far.to_bits() & 0x7f80_0000) as f64 * f32::EPSILON as f64;
    let centre = 0.5 * (lo as f64 + hi as f64);
    ((centre / q).round() * q) as f32
}

/// The shift that brings bounds `lo..=hi` next to the origin (zero on axes left alone).
pub fn shift_for(lo: Vec3, hi: Vec3) -> Vec3 {
    Vec3::new(axis_shift(lo.x, hi.x), axis_shift(lo.y, hi.y), axis_shift(lo.z, hi.z))
}

/// `scene` moved by minus its shift, and the shift (the world position of the new origin).
pub fn to_local(mut scene: Scene) -> (Scene, Vec3) {
    let origin = shift_for(scene.bounds_min, scene.bounds_max);
    if origin == Vec3::ZERO {
        return (scene, origin);
    }
    let o = origin.extend(0.0);
    for t in &mut scene.triangles {
        t.v0 -= o;
        t.v1 -= o;
        t.v2 -= o;
    }
    scene.bounds_min -= origin;
    scene.bounds_max -= origin;
    (scene, origin)
}

/// A world-space point in the frame whose origin is `origin`, rounded once (in f64 first).
pub fn point_to_local(p: Vec3, origin: Vec3) -> Vec3 {
    (p.as_dvec3() - origin.as_dvec3()).as_vec3()
}

/// A local point back in world space, rounded once.
pub fn point_to_world(p: Vec3, origin: Vec3) -> Vec3 {
    (p.as_dvec3() + origin.as_dvec3()).as_vec3()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shifts_only_axes_far_from_zero() {
        assert_eq!(axis_shift(0.0, 0.55), 0.0);
        assert_eq!(axis_shift(-3.0, 5.0), 0.0);
        assert_eq!(axis_shift(1.0, 3.0), 0.0);
        assert_eq!(axis_shift(0.0, 0.0), 0.0);
        let s = axis_shift(100_000.0, 100_000.55);
        assert!((s - 100_000.27).abs() < 0.01, "{s}");
        let s = axis_shift(-2e6, -1.5e6);
        assert!((s + 1.75e6).abs() < 1.0, "{s}");
    }

    #[test]
    fn the_move_is_exact_for_every_coordinate() {
        // Dense coordinates across the range, and both ends of the factor-of-two window.
        for (lo, hi) in [(100_000.0f32, 100_000.55f32), (1.0e5, 1.9e5), (1.5e6, 3.0e6), (-7.0e4, -4.0e4), (0.75, 1.25)]
        {
            let s = axis_shift(lo, hi);
            assert_ne!(s, 0.0, "{lo}..{hi}");
            let mut x = lo;
            let step = ((hi - lo) / 997.0).max(f32::EPSILON * hi.abs());
            while x <= hi {
                for v in [x, f32::from_bits(x.to_bits() + 1)] {
                    if v > hi {
                        continue;
                    }
                    let d = v - s;
                    assert_eq!(d as f64, v as f64 - s as f64, "{v} − {s} rounded");
                    assert_eq!((d + s).to_bits(), v.to_bits(), "{v} does not come back");
                }
                x += step;
            }
        }
    }

    #[test]
    fn a_scene_far_away_moves_next_to_the_origin() {
        let t = shared::layout::Triangle {
            v0: Vec3::new(1e5, 2e5, -3e5).extend(0.0),
            v1: Vec3::new(1e5 + 0.5, 2e5, -3e5).extend(0.0),
            v2: Vec3::new(1e5, 2e5 + 0.5, -3e5 + 0.25).extend(0.0),
        };
        let scene =
            Scene::new(vec![t], vec![0], vec![crate::scene::diffuse(Vec3::ONE, Vec3::ZERO)], vec!["m".into()]).unwrap();
        let (local, origin) = to_local(scene.clone());
        assert!(local.bounds_max.abs().max_element() < 1.0, "{:?}", local.bounds_max);
        for (a, b) in scene.triangles.iter().zip(&local.triangles) {
            for (p, q) in [(a.v0, b.v0), (a.v1, b.v1), (a.v2, b.v2)] {
                assert_eq!(point_to_world(q.truncate(), origin), p.truncate());
            }
        }
    }
}
