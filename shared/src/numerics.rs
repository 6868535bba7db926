//! Conservative floating-point tools, in one place (pbrt-v4 `ray.h`/`float.h` and its error-bound
//! ray offset, Psychopath's `fp_utils.rs`).
//!
//! Every test here works on bit patterns: Vulkan drivers may optimise `x != x` away and need not
//! produce NaNs, so self-comparison is not a reliable finiteness test on the GPU.
use crate::glam::Vec3;

/// Unit roundoff of f32 (half an ulp of 1.0).
pub const MACHINE_EPSILON: f32 = f32::EPSILON * 0.5;

/// γ(n) = nε / (1 − nε): the relative error bound of n chained roundings (pbrt-v4 §6.8.1).
#[inline]
pub const fn gamma(n: u32) -> f32 {
    let ne = n as f32 * MACHINE_EPSILON;
    ne / (1.0 - ne)
}

/// The largest coordinate, in scene units, of the scene's box and the camera in the scene's local
/// frame: the watertight triangle test (Woop et al. 2013, `triangle`) multiplies three
/// coordinate differences, which must stay below f32's largest value (3.4e38). The Cornell box
/// renders correctly with coordinates up to 7e12 and wrongly from 3e13 on; scenes and cameras
/// beyond this are refused, not rendered wrong.
pub const MAX_EXTENT: f32 = 5e12;
/// The smallest largest side a scene's box may have: the same products must stay above f32's
/// smallest normal value (1.2e-38), with room for the triangles' own, smaller, edges (the box
/// renders correctly at 2e-11 units and black at 2e-16).
pub const MIN_EXTENT: f32 = 1e-10;

/// Relative slack applied to t-intervals during k-d traversal. Split-plane distances carry about
/// γ(3) of error and watertight hit distances a few ulps of the triangle's extent along the ray;
/// widening by 2^-16 visits a node more only when a hit lies within that margin of its boundary.
pub const T_SLACK: f32 = 1.0 / 65536.0;

#[inline]
pub fn is_finite(x: f32) -> bool {
    (x.to_bits() & 0x7f80_0000) != 0x7f80_0000
}

#[inline]
pub fn is_finite3(v: Vec3) -> bool {
    is_finite(v.x) & is_finite(v.y) & is_finite(v.z)
}

/// The next representable f32 above `x` (Psychopath's `next_float_up`).
#[inline]
pub fn next_float_up(x: f32) -> f32 {
    if !is_finite(x) && x > 0.0 {
        return x;
    }
    let x = if x == -0.0 { 0.0 } else { x };
    let bits = x.to_bits();
    let bits = if x >= 0.0 { bits + 1 } else { bits - 1 };
    f32::from_bits(bits)
}

/// The next representable f32 below `x`.
#[inline]
pub fn next_float_down(x: f32) -> f32 {
    if !is_finite(x) && x < 0.0 {
        return x;
    }
    let x = if x == 0.0 { -0.0 } else { x };
    let bits = x.to_bits();
    let bits = if x > 0.0 { bits - 1 } else { bits + 1 };
    f32::from_bits(bits)
}

/// Moves a surface point off its surface so that a ray spawned from it cannot hit that surface
/// again (pbrt-v4 `OffsetRayOrigin`, §6.8.6): `p` lies within `error` of the true surface point
/// on each axis; the origin moves along the unit normal `n` (pointing to the side the new ray
/// leaves from) by the error box's extent along `n`, then one more ulp away on each axis to
/// absorb the rounding of that addition. Multiplies, adds and bit steps only: identical on the
/// CPU and the GPU.
#[inline]
pub fn offset_ray_origin(p: Vec3, error: Vec3, n: Vec3) -> Vec3 {
    let d = n.x.abs() * error.x + n.y.abs() * error.y + n.z.abs() * error.z;
    let offset = n * d;
    Vec3::new(step_away(p.x + offset.x, n.x), step_away(p.y + offset.y, n.y), step_away(p.z + offset.z, n.z))
}

/// `next_float_up(x)` where `direction` > 0, `next_float_down(x)` where it is < 0, else `x`, by
/// selects: the same bits as those two on every input (NaN included, unit test), but no branch,
/// so that each of a shader's inlined ray offsets is a few dozen instructions, not a tree of
/// blocks.
#[inline]
fn step_away(x: f32, direction: f32) -> f32 {
    let (up, down) = (direction > 0.0, direction < 0.0);
    let bits = x.to_bits();
    // One ulp further from zero where x lies on the side it moves to, one nearer where it lies
    // on the other (NaN: as the comparisons in `next_float_up` and `next_float_down` take it);
    // from either zero to the smallest value of that side.
    let further = if up { x >= 0.0 } else { !(x > 0.0) };
    let stepped = if further { bits.wrapping_add(1) } else { bits.wrapping_sub(1) };
    let from_zero = if up { 1 } else { 0x8000_0001 };
    let stepped = if x == 0.0 { from_zero } else { stepped };
    // An infinity moving outward stays, as does x with no direction.
    let stays = (up & (bits == 0x7f80_0000)) | (down & (bits == 0xff80_0000)) | !(up | down);
    f32::from_bits(if stays { bits } else { stepped })
}

/// The power of two 2^-e, where 2^e ≤ x < 2^(e+1): multiplying by it is exact and brings a
/// positive normal `x` into [1, 2). For 0 (and subnormal `x`) it is 2^127, for `x` at or above
/// 2^127 it is 0: callers pass magnitudes far inside that range.
#[inline]
pub fn inverse_power_of_two(x: f32) -> f32 {
    let e = (x.to_bits() >> 23) & 0xff;
    f32::from_bits(254u32.saturating_sub(e) << 23)
}

/// Zeroes a non-finite or negative radiance sample. Returns the sample and whether it was bad.
#[inline]
pub fn sanitize_radiance(l: Vec3) -> (Vec3, bool) {
    sanitize(l, false)
}

/// `sanitize_radiance` for values that may be negative (a normal image): only non-finite ones
/// are zeroed unless `signed` is false.
#[inline]
pub fn sanitize(l: Vec3, signed: bool) -> (Vec3, bool) {
    let negative = (l.x < 0.0) | (l.y < 0.0) | (l.z < 0.0);
    let bad = !is_finite3(l) | (negative & !signed);
    if bad {
        (Vec3::ZERO, true)
    } else {
        (l, false)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finiteness_by_bits() {
        assert!(is_finite(0.0) && is_finite(-1e38) && is_finite(f32::MIN_POSITIVE / 2.0));
        assert!(!is_finite(f32::NAN) && !is_finite(f32::INFINITY) && !is_finite(f32::NEG_INFINITY));
    }

    #[test]
    fn float_steps_are_one_ulp() {
        for &x in &[1.0f32, -1.0, 0.0, -0.0, 1e-30, -3.5e7, f32::MAX / 2.0] {
            let up = next_float_up(x);
            let down = next_float_down(x);
            assert!(up > x && down < x, "{x}: {down} {up}");
            assert_eq!(next_float_down(up), if x == 0.0 { 0.0 } else { x });
        }
    }

    /// The branches `step_away` replaces, as they were.
    fn step_away_by_branches(x: f32, direction: f32) -> f32 {
        if direction > 0.0 {
            next_float_up(x)
        } else if direction < 0.0 {
            next_float_down(x)
        } else {
            x
        }
    }

    #[test]
    fn step_away_matches_next_float_up_and_down_bit_for_bit() {
        let directions = [1.0f32, -1.0, 0.0, -0.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e-40, -1e-40];
        let special = [0u32, 0x8000_0000, 1, 0x8000_0001, 0x7f80_0000, 0xff80_0000, 0x7f7f_ffff, 0xff7f_ffff];
        let nans = [0x7fc0_0000u32, 0xffc0_0000, 0x7f80_0001, 0xff80_0001, 0x7fff_ffff, 0xffff_ffff];
        // Every 65,521st bit pattern (a prime stride, so all exponents and many mantissas).
        let strided = (0..=u32::MAX / 65_521).map(|i| i * 65_521);
        for bits in special.into_iter().chain(nans).chain(strided) {
            let x = f32::from_bits(bits);
            for d in directions {
                let (got, want) = (step_away(x, d).to_bits(), step_away_by_branches(x, d).to_bits());
                assert_eq!(got, want, "x = {bits:#010x}, direction {d}");
            }
        }
    }

    #[test]
    fn offset_moves_to_the_normal_side_by_the_error_bound() {
        for &p in &[1e-6f32, -0.01, 1.0, -1.0, 1e4, -1e4, 1e6] {
            for &n in &[1.0f32, -1.0] {
                let error = Vec3::splat(p.abs() * gamma(7));
                let q = offset_ray_origin(Vec3::splat(p), error, Vec3::new(n, 0.0, 0.0));
                assert!((q.x - p) * n > 0.0, "p={p} n={n} q={}", q.x);
                assert!((q.x - p).abs() >= error.x, "p={p}: moved {} < error {}", (q.x - p).abs(), error.x);
                assert_eq!((q.y, q.z), (p, p), "no offset across the normal");
            }
        }
        // An exact point still moves by an ulp along the normal.
        assert!(offset_ray_origin(Vec3::ZERO, Vec3::ZERO, Vec3::Z).z > 0.0);
        // Tiny scenes get tiny offsets: nothing like a fixed epsilon.
        let q = offset_ray_origin(Vec3::splat(1e-6), Vec3::splat(1e-6 * gamma(7)), Vec3::X);
        assert!(q.x - 1e-6 < 1e-11);
    }

    #[test]
    fn sanitize_catches_nan_inf_and_negative() {
        assert!(sanitize_radiance(Vec3::new(f32::NAN, 0.0, 0.0)).1);
        assert!(sanitize_radiance(Vec3::new(0.0, f32::INFINITY, 0.0)).1);
        assert!(sanitize_radiance(Vec3::new(0.0, 0.0, -1.0)).1);
        assert_eq!(sanitize_radiance(Vec3::new(1.0, 2.0, 3.0)), (Vec3::new(1.0, 2.0, 3.0), false));
    }
}
