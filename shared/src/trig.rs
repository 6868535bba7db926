//! Sine and cosine as polynomials on [-π/4, π/4].
//!
//! Vulkan lets `sin`/`cos` be off by 2^-11 absolute and lavapipe differs from Rust's libm by an ulp;
//! the samplers only need angles in this range (concentric disk mapping), where the Taylor series
//! truncated after x^9 (sin) and x^10 (cos) is below f32 resolution (|error| < 2e-9).
//! Both devices run exactly these multiplies and adds, so they draw identical directions.

/// sin(x) for |x| ≤ π/4.
#[inline]
pub fn sin_quarter(x: f32) -> f32 {
    let x2 = x * x;
    x * (1.0 + x2 * (-1.0 / 6.0 + x2 * (1.0 / 120.0 + x2 * (-1.0 / 5040.0 + x2 * (1.0 / 362880.0)))))
}

/// cos(x) for |x| ≤ π/4.
#[inline]
pub fn cos_quarter(x: f32) -> f32 {
    let x2 = x * x;
    1.0 + x2 * (-0.5 + x2 * (1.0 / 24.0 + x2 * (-1.0 / 720.0 + x2 * (1.0 / 40320.0 + x2 * (-1.0 / 3628800.0)))))
}

/// sin and cos of the angle 2π·`t` for `t` in [0, 1): the quadrant from `4t` (exact), the angle
/// within it folded onto [0, π/4] so that `sin_quarter`/`cos_quarter` apply. Only exactly
/// rounded operations, so both devices get the same bits. Returns (sin, cos).
#[inline]
pub fn sincos_turns(t: f32) -> (f32, f32) {
    sincos_turns_with(t, core::f32::consts::FRAC_PI_2)
}

/// `sincos_turns` with π/2 given (`half_pi`): a shader that reads it from a buffer keeps the
/// driver from reassociating the products of the angle with constants.
#[inline]
pub fn sincos_turns_with(t: f32, half_pi: f32) -> (f32, f32) {
    let t4 = t * 4.0;
    let q = if t4 < 0.0 {
        0
    } else if t4 < 3.0 {
        t4 as u32
    } else {
        3
    };
    let g = t4 - q as f32;
    // sin and cos of ψ = g·π/2 in [0, π/2].
    let (s, c) = if g < 0.5 {
        let a = g * half_pi;
        (sin_quarter(a), cos_quarter(a))
    } else {
        let h = (q + 1) as f32 - t4;
        let a = h * half_pi;
        (cos_quarter(a), sin_quarter(a))
    };
    if q == 0 {
        (s, c)
    } else if q == 1 {
        (c, -s)
    } else if q == 2 {
        (-s, -c)
    } else {
        (-c, s)
    }
}

/// atan(x) for x in [0, 1] as (whether π/4 is to be added, the rest): above tan(π/8),
/// atan(x) = π/4 + atan((x − 1)/(x + 1)); the rest by the Taylor series to x^19 (|x| ≤ 0.4143:
/// error below 1e-8). The constant stays apart so that no device folds it into other constants
/// (Mesa reassociates sums with constants, which changes the rounding).
#[inline]
fn atan_unit(x: f32) -> (bool, f32) {
    let big = x > 0.414_213_57;
    let t = if big { (x - 1.0) / (x + 1.0) } else { x };
    let t2 = t * t;
    let p = 1.0
        + t2 * (-1.0 / 3.0
            + t2 * (1.0 / 5.0
                + t2 * (-1.0 / 7.0
                    + t2 * (1.0 / 9.0
                        + t2 * (-1.0 / 11.0
                            + t2 * (1.0 / 13.0 + t2 * (-1.0 / 15.0 + t2 * (1.0 / 17.0 + t2 * (-1.0 / 19.0)))))))));
    (big, t * p)
}

/// k·π/4 for k in 0..=4, each an f32 literal.
#[inline(always)]
fn quarter_pi_multiple(k: u32) -> f32 {
    if k == 0 {
        0.0
    } else if k == 1 {
        core::f32::consts::FRAC_PI_4
    } else if k == 2 {
        core::f32::consts::FRAC_PI_2
    } else if k == 3 {
        2.356_194_5
    } else {
        core::f32::consts::PI
    }
}

/// atan2(y, x) in (−π, π] from exactly rounded operations (one or two divisions): the same bits
/// on every device, written as k·π/4 ± r with k chosen, never summed from constants.
/// atan2(0, 0) = 0.
#[inline]
pub fn atan2(y: f32, x: f32) -> f32 {
    let ax = x.abs();
    let ay = y.abs();
    let hi = if ax > ay { ax } else { ay };
    let lo = if ax > ay { ay } else { ax };
    let (big, r) = if hi > 0.0 { atan_unit(lo / hi) } else { (false, 0.0) };
    // value = k·π/4 + sign·r
    let mut k = if big { 1 } else { 0 };
    let mut positive = true;
    if ay > ax {
        k = 2 - k;
        positive = !positive;
    }
    if x < 0.0 {
        k = 4 - k;
        positive = !positive;
    }
    let base = quarter_pi_multiple(k);
    let value = if positive { base + r } else { base - r };
    if y < 0.0 {
        -value
    } else {
        value
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_libm_on_the_quarter_circle() {
        let mut worst = 0.0f64;
        for i in 0..=100_000 {
            let x = -core::f32::consts::FRAC_PI_4 + core::f32::consts::FRAC_PI_2 * (i as f32 / 100_000.0);
            let xs = (x as f64).sin();
            let xc = (x as f64).cos();
            worst = worst.max((sin_quarter(x) as f64 - xs).abs()).max((cos_quarter(x) as f64 - xc).abs());
        }
        // Two ulps of 1.0 at most: the polynomial itself is exact to 2e-9, the rest is f32 rounding.
        assert!(worst < 2.5e-7, "worst error {worst}");
    }

    #[test]
    fn full_turn_and_atan2_match_libm() {
        let mut worst = 0.0f64;
        for i in 0..100_000 {
            let t = i as f32 / 100_000.0;
            let (s, c) = sincos_turns(t);
            let a = 2.0 * core::f64::consts::PI * t as f64;
            worst = worst.max((s as f64 - a.sin()).abs()).max((c as f64 - a.cos()).abs());
            let (y, x) = (a.sin() as f32 * 3.0, a.cos() as f32 * 3.0);
            let e = (atan2(y, x) as f64 - (y as f64).atan2(x as f64)).abs();
            worst = worst.max(e.min((e - 2.0 * core::f64::consts::PI).abs()));
        }
        assert!(worst < 1e-6, "worst error {worst}");
        assert_eq!(atan2(0.0, 0.0), 0.0);
    }
}
