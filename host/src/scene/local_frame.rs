//! Scene-relative coordinates: a scene far from the world origin (a building at survey
//! coordinates, a level tile at 1e5) is moved next to the origin before its tree is built, and
//! the camera with it, so rendering runs on small numbers.
//!
//! Vertices, placements and the camera stay in f64 from the file to this move (`place`), and
//! each coordinate is rounded to f32 once, after it: at easting 4e5 or northing 6e6 an f32 world
//! coordinate is a 1/32 or 1/2 unit step, but the same point relative to the scene is exact to
//! f32's 24 bits of its distance from the scene's origin.
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
use crate::scene::{widen_triangle, Scene, WorldTriangle};
use shared::glam::{DVec3, Vec3};
use shared::layout::Triangle;

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

/// The shift that brings bounds `lo..=hi` next to the origin (zero on axes left alone). It is
/// chosen on the bounds rounded to f32, so that a scene whose coordinates are f32 values moves
/// exactly (module docs); coordinates with more digits are moved in f64 and rounded once.
pub fn shift_for(lo: DVec3, hi: DVec3) -> DVec3 {
    let axis = |l: f64, h: f64| axis_shift(l as f32, h as f32) as f64;
    DVec3::new(axis(lo.x, hi.x), axis(lo.y, hi.y), axis(lo.z, hi.z))
}

/// The world triangles in the local frame, each coordinate rounded to f32 once, and the world
/// position of the frame's origin. Non-finite coordinates are left for `Scene::new` to refuse.
pub fn place(world: &[WorldTriangle]) -> (Vec<Triangle>, DVec3) {
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for v in world.iter().flatten().filter(|v| v.is_finite()) {
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    let origin = if lo.x <= hi.x { shift_for(lo, hi) } else { DVec3::ZERO };
    let local = |v: DVec3| point_to_local(v, origin).extend(0.0);
    (world.iter().map(|t| Triangle { v0: local(t[0]), v1: local(t[1]), v2: local(t[2]) }).collect(), origin)
}

/// An f32 `scene` moved by minus its shift (`place`), and the shift (the world position of the
/// new origin). Every move is exact here (module docs).
pub fn to_local(mut scene: Scene) -> (Scene, DVec3) {
    let world: Vec<WorldTriangle> = scene.triangles.iter().map(widen_triangle).collect();
    let (triangles, origin) = place(&world);
    scene.triangles = triangles;
    scene.bounds_min = point_to_local(scene.bounds_min.as_dvec3(), origin);
    scene.bounds_max = point_to_local(scene.bounds_max.as_dvec3(), origin);
    (scene, origin)
}

/// A world-space point in the frame whose origin is `origin`, rounded once.
pub fn point_to_local(p: DVec3, origin: DVec3) -> Vec3 {
    (p - origin).as_vec3()
}

/// A local point back in world space, in f64.
pub fn point_to_world(p: Vec3, origin: DVec3) -> DVec3 {
    p.as_dvec3() + origin
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
                assert_eq!(point_to_world(q.truncate(), origin), p.truncate().as_dvec3());
            }
        }
    }

    #[test]
    fn survey_coordinates_keep_their_digits() {
        // Easting, elevation and northing of a site, and three corners a metre or so apart.
        let site = DVec3::new(412_345.0, 12.5, 6_123_456.0);
        let offsets = [
            DVec3::new(0.123_456_789, 0.5, 0.987_654_321),
            DVec3::new(1.75, 0.25, 0.015_625),
            DVec3::new(0.3, 1.1, 1.7),
        ];
        let world: Vec<WorldTriangle> = vec![offsets.map(|o| site + o)];
        let (local, _) = place(&world);
        let local = [local[0].v0, local[0].v1, local[0].v2].map(|v| v.truncate().as_dvec3());
        let rounded = world[0].map(|v| v.as_vec3().as_dvec3());
        let (mut local_err, mut rounded_err) = (0f64, 0f64);
        for k in 1..3 {
            let shape = offsets[k] - offsets[0];
            local_err = local_err.max(((local[k] - local[0]) - shape).abs().max_element());
            rounded_err = rounded_err.max(((rounded[k] - rounded[0]) - shape).abs().max_element());
        }
        // The local frame keeps the shape to f32's step at a metre; f32 world coordinates
        // would move corners by up to half of 0.5 m at northing 6e6.
        assert!(local_err < 1e-6, "local frame: {local_err}");
        assert!(rounded_err > 0.01, "f32 world coordinates: {rounded_err}");
    }
}
