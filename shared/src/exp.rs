//! The exponential for Beer–Lambert absorption, as our own arithmetic so that the CPU and every
//! device compute the same bits (a shader's `exp` is the driver's, which differs from the
//! CPU's by an ulp or more). Cody–Waite range reduction (Cody & Waite 1980, "Software Manual
//! for the Elementary Functions"): x = n·ln 2 + r with |r| ≤ ln 2 / 2, e^r by its Taylor series,
//! 2^n by building the float's exponent bits.
#[allow(unused_imports)]
use spirv_std::num_traits::Float;

/// ln 2 in two parts: `LN2_HI` has its low bits zero, so n·`LN2_HI` is exact for |n| < 2^11.
const LN2_HI: f32 = 0.693_145_75;
const LN2_LO: f32 = 1.428_606_8e-6;

/// e^x for x ≤ 0 (attenuation): below −87 (where e^x leaves the normal floats) 0; relative
/// error below 4e-7.
#[inline]
pub fn exp_neg(x: f32) -> f32 {
    if !(x > -87.0) {
        return 0.0;
    }
    if x >= 0.0 {
        return 1.0;
    }
    // n = round(x / ln 2), in [−126, 0].
    let n = (x * core::f32::consts::LOG2_E - 0.5).ceil();
    // Each product stands alone: a device must not fuse them into the subtractions.
    let hi = n * LN2_HI;
    let lo = n * LN2_LO;
    let r = (x - hi) - lo;
    // e^r, |r| ≤ 0.347: the series to r^7 leaves 0.347^8/8! ≈ 5e-9.
    let p = 1.0
        + r * (1.0
            + r * (1.0 / 2.0
                + r * (1.0 / 6.0 + r * (1.0 / 24.0 + r * (1.0 / 120.0 + r * (1.0 / 720.0 + r * (1.0 / 5040.0)))))));
    let scale = f32::from_bits(((n as i32 + 127) as u32) << 23);
    p * scale
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_library_exponential() {
        let mut worst = 0f64;
        let mut x = 0.0f32;
        while x > -87.0 {
            let want = (x as f64).exp();
            let got = exp_neg(x) as f64;
            worst = worst.max(((got - want) / want).abs());
            x -= 0.0137;
        }
        assert!(worst < 4e-7, "worst relative error {worst:e}");
        assert_eq!(exp_neg(0.0), 1.0);
        assert_eq!(exp_neg(-100.0), 0.0);
        assert_eq!(exp_neg(f32::NEG_INFINITY), 0.0);
        assert_eq!(exp_neg(f32::NAN), 0.0);
    }
}
