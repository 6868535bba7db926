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
}
