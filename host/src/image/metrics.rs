//! Image error metrics for comparing a render against a reference, and the per-pixel test of a
//! render's sample statistics against a reference.
//!
//! - RMSE and MAE over all channel values.
//! - relMSE = mean((x − r)² / (r² + ε)), ε = 0.01: the relative MSE of Rousselle, Knaus and
//!   Zwicker ("Adaptive Sampling and Reconstruction using Greedy Error Minimization", SIGGRAPH Asia
//!   2011); ε keeps black reference pixels from dominating.
//! - ꟻLIP: the LDR ꟻLIP of Andersson et al., "FLIP: A Difference Evaluator for Alternating Images"
//!   (HPG 2020), computed by NVIDIA's own C++ implementation through the `nv-flip` crate. LDR ꟻLIP
//!   takes sRGB images: both linear images are encoded exactly as our PNG output is (clamped to
//!   [0, 1], sRGB transfer, 8 bits), so ꟻLIP measures what a viewer of the PNGs would see.
//!   `tests/flip_reference.rs` checks it against the values of NVIDIA's `flip-evaluator` package.
//! - NaN and ±Inf counts per image. A channel value that is non-finite in either image is left
//!   out of RMSE, relMSE and MAE (and counted), so one NaN does not hide the error of the rest.
//!
//! The per-pixel test (`mean_test`, `pixel_test`) is a one-sample test of each pixel channel's
//! estimated mean against the reference value, given the per-sample variance and the sample
//! count, with Šidák's correction (Šidák 1967) so that the chance of any false rejection over the
//! whole image is α. It uses Student's t with n − 1 degrees of freedom, which is exact for
//! normal samples and becomes the z-test for large n.
use crate::image::io::linear_to_srgb;
use anyhow::{bail, Result};
use serde::Serialize;
use statrs::distribution::{ContinuousCDF, StudentsT};

/// ε of relMSE.
pub const RELMSE_EPSILON: f64 = 0.01;

/// A linear RGB image, rows top to bottom.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
}

impl LinearImage {
    pub fn new(width: u32, height: u32, pixels: Vec<[f32; 3]>) -> Result<Self> {
        if pixels.len() != width as usize * height as usize {
            bail!("{} pixels for a {width}x{height} image", pixels.len());
        }
        Ok(Self { width, height, pixels })
    }

    /// The image as 8-bit sRGB, as written to PNG (non-finite values become 0).
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.pixels.iter().flat_map(|p| p.map(|c| (linear_to_srgb(c) * 255.0 + 0.5) as u8)).collect()
    }
}

/// Counts of non-finite channel values in one image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct NonFinite {
    pub nan: u64,
    pub inf: u64,
}

impl NonFinite {
    pub fn of(img: &LinearImage) -> Self {
        let mut n = Self::default();
        for c in img.pixels.iter().flatten() {
            n.nan += c.is_nan() as u64;
            n.inf += c.is_infinite() as u64;
        }
        n
    }
}

/// Everything `kdtrace compare` reports.
#[derive(Clone, Debug, Serialize)]
pub struct Errors {
    pub width: u32,
    pub height: u32,
    pub rmse: f64,
    pub relmse: f64,
    pub mae: f64,
    /// Mean LDR ꟻLIP error in [0, 1].
    pub flip: f64,
    /// Pixels per degree of visual angle used for ꟻLIP.
    pub flip_ppd: f32,
    /// Mean of the test image over the mean of the reference (finite channel values of both).
    pub mean_ratio: f64,
    pub reference_nonfinite: NonFinite,
    pub test_nonfinite: NonFinite,
    /// Channel values left out of RMSE, relMSE and MAE because either image is non-finite there.
    pub skipped_values: u64,
}

/// RMSE, relMSE, MAE, mean ratio and the count of skipped values, without ꟻLIP.
pub fn pointwise(reference: &LinearImage, test: &LinearImage) -> Result<(f64, f64, f64, f64, u64)> {
    check_sizes(reference, test)?;
    let (mut se, mut rel, mut ae, mut sr, mut sx, mut n, mut skipped) = (0f64, 0f64, 0f64, 0f64, 0f64, 0u64, 0u64);
    for (pr, px) in reference.pixels.iter().zip(&test.pixels) {
        for k in 0..3 {
            let (r, x) = (pr[k] as f64, px[k] as f64);
            if !(r.is_finite() && x.is_finite()) {
                skipped += 1;
                continue;
            }
            let d = x - r;
            se += d * d;
            rel += d * d / (r * r + RELMSE_EPSILON);
            ae += d.abs();
            sr += r;
            sx += x;
            n += 1;
        }
    }
    if n == 0 {
        return Ok((f64::NAN, f64::NAN, f64::NAN, f64::NAN, skipped));
    }
    let nf = n as f64;
    Ok(((se / nf).sqrt(), rel / nf, ae / nf, sx / sr, skipped))
}

/// Mean LDR ꟻLIP of `test` against `reference` at `ppd` pixels per degree.
pub fn flip(reference: &LinearImage, test: &LinearImage, ppd: f32) -> Result<f64> {
    check_sizes(reference, test)?;
    Ok(flip_srgb8(reference.width, reference.height, &reference.to_srgb8(), &test.to_srgb8(), ppd).0)
}

/// Mean ꟻLIP and the per-pixel ꟻLIP map of two 8-bit sRGB images of the same size.
pub fn flip_srgb8(width: u32, height: u32, reference: &[u8], test: &[u8], ppd: f32) -> (f64, Vec<f32>) {
    assert_eq!(reference.len(), width as usize * height as usize * 3);
    assert_eq!(test.len(), reference.len());
    let r = nv_flip::FlipImageRgb8::with_data(width, height, reference);
    let t = nv_flip::FlipImageRgb8::with_data(width, height, test);
    let map = nv_flip::flip(r, t, ppd);
    // FlipPool's mean is what NVIDIA's tool prints as "Mean".
    let mean = nv_flip::FlipPool::from_image(&map).mean() as f64;
    (mean, map.to_vec())
}

/// All metrics at ꟻLIP's default 67 pixels per degree (a 0.7 m wide 4K monitor seen from 0.7 m).
pub fn errors(reference: &LinearImage, test: &LinearImage) -> Result<Errors> {
    let (rmse, relmse, mae, mean_ratio, skipped_values) = pointwise(reference, test)?;
    let flip_ppd = nv_flip::DEFAULT_PIXELS_PER_DEGREE;
    Ok(Errors {
        width: reference.width,
        height: reference.height,
        rmse,
        relmse,
        mae,
        flip: flip(reference, test, flip_ppd)?,
        flip_ppd,
        mean_ratio,
        reference_nonfinite: NonFinite::of(reference),
        test_nonfinite: NonFinite::of(test),
        skipped_values,
    })
}

fn check_sizes(a: &LinearImage, b: &LinearImage) -> Result<()> {
    if (a.width, a.height) != (b.width, b.height) {
        bail!("images of different sizes: {}x{} and {}x{}", a.width, a.height, b.width, b.height);
    }
    Ok(())
}

/// Šidák's per-test level: with `tests` independent tests each at this level, the chance of one
/// or more false rejections is exactly `alpha`. 1 − (1 − α)^(1/m), written with ln1p/expm1 so it
/// stays accurate when α/m is tiny.
pub fn sidak_alpha(alpha: f64, tests: u64) -> f64 {
    assert!(alpha > 0.0 && alpha < 1.0 && tests > 0);
    -((-alpha).ln_1p() / tests as f64).exp_m1()
}

/// Two-sided p-value of "the true mean is `reference`" for an estimate `mean` of `count` samples
/// whose per-sample variance is estimated as `variance` (unbiased, n − 1 denominator).
///
/// `None` when the test cannot be made (fewer than two samples, negative variance). A non-finite
/// mean or variance gives p = 0: a NaN pixel is an error, not an untestable pixel. A zero
/// variance (all samples equal) gives p = 1 when the mean is the reference and 0 otherwise.
pub fn mean_test(reference: f64, mean: f64, variance: f64, count: u64) -> Option<f64> {
    if count < 2 || variance < 0.0 || !reference.is_finite() {
        return None;
    }
    if !(mean.is_finite() && variance.is_finite()) {
        return Some(0.0);
    }
    let d = mean - reference;
    if variance == 0.0 {
        return Some(if d == 0.0 { 1.0 } else { 0.0 });
    }
    let t = d / (variance / count as f64).sqrt();
    let dist = StudentsT::new(0.0, 1.0, (count - 1) as f64).expect("degrees of freedom ≥ 1");
    // sf(|t|) rather than 1 − cdf: the tail is what matters and must not round to 0.
    Some((2.0 * dist.sf(t.abs())).min(1.0))
}

/// Per-pixel statistics of a render: for each pixel the mean and per-sample variance of each
/// channel, and the sample count (what `render --variance` is to write).
#[derive(Clone, Debug)]
pub struct PixelStats {
    pub mean: LinearImage,
    pub variance: LinearImage,
    pub count: Vec<u64>,
}

impl PixelStats {
    /// Per pixel channel the mean and unbiased variance over independent images of one scene
    /// (renders with different seeds): each image one sample of the pixel's estimator, so the
    /// test needs nothing of how each image was sampled (adaptive or not).
    pub fn of_images(width: u32, height: u32, images: &[Vec<[f32; 3]>]) -> Result<Self> {
        let n = (width * height) as usize;
        if images.len() < 2 || images.iter().any(|i| i.len() != n) {
            bail!("{} images for {width}x{height} pixels: need two or more of that size", images.len());
        }
        let k = images.len() as f64;
        let (mut s1, mut s2) = (vec![[0f64; 3]; n], vec![[0f64; 3]; n]);
        for image in images {
            for (i, p) in image.iter().enumerate() {
                for c in 0..3 {
                    s1[i][c] += p[c] as f64;
                    s2[i][c] += p[c] as f64 * p[c] as f64;
                }
            }
        }
        let mean = s1.iter().map(|a| a.map(|v| (v / k) as f32)).collect();
        let variance = s1
            .iter()
            .zip(&s2)
            .map(|(a, b)| [0, 1, 2].map(|c| ((b[c] - a[c] * a[c] / k) / (k - 1.0)).max(0.0) as f32))
            .collect();
        Ok(Self {
            mean: LinearImage::new(width, height, mean)?,
            variance: LinearImage::new(width, height, variance)?,
            count: vec![images.len() as u64; n],
        })
    }
}

/// The outcome of `pixel_test`.
#[derive(Clone, Debug, Serialize)]
pub struct PixelTest {
    /// Channel values tested.
    pub tests: u64,
    /// Channel values that could not be tested (count < 2).
    pub untested: u64,
    pub alpha: f64,
    /// Šidák-corrected level each channel value is tested at.
    pub per_test_alpha: f64,
    /// Channel values rejected at `per_test_alpha`.
    pub rejected: u64,
    pub min_p: f64,
    /// (x, y, channel) of the smallest p-value.
    pub worst: Option<(u32, u32, usize)>,
    /// No rejection: the render is consistent with the reference at level α.
    pub pass: bool,
}

/// Tests every pixel channel of `stats` against `reference` (exact values, or a reference whose
/// own noise is negligible), at family-wise level `alpha` with Šidák's correction.
pub fn pixel_test(reference: &LinearImage, stats: &PixelStats, alpha: f64) -> Result<PixelTest> {
    check_sizes(reference, &stats.mean)?;
    check_sizes(reference, &stats.variance)?;
    if stats.count.len() != reference.pixels.len() {
        bail!("{} sample counts for {} pixels", stats.count.len(), reference.pixels.len());
    }
    let mut ps = Vec::with_capacity(reference.pixels.len() * 3);
    let mut untested = 0;
    for (i, r) in reference.pixels.iter().enumerate() {
        for (k, &rk) in r.iter().enumerate() {
            match mean_test(
                rk as f64,
                stats.mean.pixels[i][k] as f64,
                stats.variance.pixels[i][k] as f64,
                stats.count[i],
            ) {
                Some(p) => ps.push((p, i, k)),
                None => untested += 1,
            }
        }
    }
    Ok(summarize(&ps, untested, alpha, reference.width))
}

/// The family-wise verdict over per-channel p-values `(p, pixel, channel)`: each tested at
/// Šidák's level for family-wise `alpha`.
fn summarize(ps: &[(f64, usize, usize)], untested: u64, alpha: f64, width: u32) -> PixelTest {
    let tests = ps.len() as u64;
    let per_test_alpha = if tests > 0 { sidak_alpha(alpha, tests) } else { alpha };
    let rejected = ps.iter().filter(|(p, _, _)| *p < per_test_alpha).count() as u64;
    let worst = ps.iter().min_by(|a, b| a.0.total_cmp(&b.0)).copied();
    PixelTest {
        tests,
        untested,
        alpha,
        per_test_alpha,
        rejected,
        min_p: worst.map_or(1.0, |w| w.0),
        worst: worst.map(|(_, i, k)| (i as u32 % width, i as u32 / width, k)),
        pass: rejected == 0,
    }
}

/// Two-sided p-value of "both estimates have the same true mean" (Welch's t-test): estimates
/// `mean_a`, `mean_b` of `count_a`, `count_b` samples with per-sample variances `var_a`, `var_b`.
/// `None` when either has fewer than two samples; the same zero-variance and non-finite rules as
/// `mean_test`.
pub fn two_sample_test(mean_a: f64, var_a: f64, count_a: u64, mean_b: f64, var_b: f64, count_b: u64) -> Option<f64> {
    if count_a < 2 || count_b < 2 || var_a < 0.0 || var_b < 0.0 {
        return None;
    }
    if !(mean_a.is_finite() && mean_b.is_finite() && var_a.is_finite() && var_b.is_finite()) {
        return Some(0.0);
    }
    let (sa, sb) = (var_a / count_a as f64, var_b / count_b as f64);
    let d = mean_a - mean_b;
    if sa + sb == 0.0 {
        return Some(if d == 0.0 { 1.0 } else { 0.0 });
    }
    let t = d / (sa + sb).sqrt();
    // Welch–Satterthwaite degrees of freedom.
    let dof = (sa + sb).powi(2) / (sa * sa / (count_a - 1) as f64 + sb * sb / (count_b - 1) as f64);
    let dist = StudentsT::new(0.0, 1.0, dof.max(1.0)).expect("degrees of freedom ≥ 1");
    Some((2.0 * dist.sf(t.abs())).min(1.0))
}

/// Tests every pixel channel of two noisy renders of the same scene (a CPU and a GPU render with
/// different seeds, say) for equal means, at family-wise level `alpha` with Šidák's correction.
pub fn two_image_test(a: &PixelStats, b: &PixelStats, alpha: f64) -> Result<PixelTest> {
    check_sizes(&a.mean, &b.mean)?;
    check_sizes(&a.mean, &a.variance)?;
    check_sizes(&b.mean, &b.variance)?;
    let width = a.mean.width;
    let mut ps = Vec::with_capacity(a.mean.pixels.len() * 3);
    let mut untested = 0;
    for i in 0..a.mean.pixels.len() {
        for k in 0..3 {
            let p = two_sample_test(
                a.mean.pixels[i][k] as f64,
                a.variance.pixels[i][k] as f64,
                a.count[i],
                b.mean.pixels[i][k] as f64,
                b.variance.pixels[i][k] as f64,
                b.count[i],
            );
            match p {
                Some(p) => ps.push((p, i, k)),
                None => untested += 1,
            }
        }
    }
    Ok(summarize(&ps, untested, alpha, width))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(w: u32, h: u32, f: impl Fn(u32, u32) -> [f32; 3]) -> LinearImage {
        LinearImage::new(w, h, (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| f(x, y)).collect())
            .unwrap()
    }

    #[test]
    fn identical_images_have_zero_error() {
        let a = img(16, 8, |x, y| [x as f32 / 16.0, y as f32 / 8.0, 0.3]);
        let e = errors(&a, &a).unwrap();
        assert_eq!((e.rmse, e.relmse, e.mae, e.flip, e.mean_ratio), (0.0, 0.0, 0.0, 0.0, 1.0));
        assert_eq!((e.reference_nonfinite, e.skipped_values), (NonFinite::default(), 0));
    }

    #[test]
    fn known_values_on_a_two_pixel_image() {
        // Reference (0.1, 0.1, 0.1), (1, 1, 1); test adds 0.1 to the first pixel and 0.3 to the
        // second: squared errors 0.01 ×3, 0.09 ×3.
        let r = LinearImage::new(2, 1, vec![[0.1; 3], [1.0; 3]]).unwrap();
        let t = LinearImage::new(2, 1, vec![[0.2; 3], [1.3; 3]]).unwrap();
        let (rmse, relmse, mae, ratio, skipped) = pointwise(&r, &t).unwrap();
        assert!((rmse - (0.05f64).sqrt()).abs() < 1e-7, "{rmse}");
        // (0.01 / (0.01 + 0.01) + 0.09 / (1 + 0.01)) / 2 = (0.5 + 0.0891089) / 2.
        assert!((relmse - (0.5 + 0.09 / 1.01) / 2.0).abs() < 1e-6, "{relmse}");
        assert!((mae - 0.2).abs() < 1e-7, "{mae}");
        assert!((ratio - 1.5 / 1.1).abs() < 1e-6, "{ratio}");
        assert_eq!(skipped, 0);
    }

    #[test]
    fn rmse_mae_flip_are_symmetric_and_relmse_is_not() {
        let a = img(8, 8, |x, y| [(x * y) as f32 / 64.0, 0.5, x as f32]);
        let b = img(8, 8, |x, y| [(x + y) as f32 / 16.0, 0.25, 0.0]);
        let (ab, ba) = (pointwise(&a, &b).unwrap(), pointwise(&b, &a).unwrap());
        assert_eq!(ab.0, ba.0);
        assert_eq!(ab.2, ba.2);
        assert!((ab.1 - ba.1).abs() > 1e-3, "relMSE divides by the reference");
        // LDR ꟻLIP is symmetric too: each image goes through the same filters and Hunt adjustment
        // on its own, the colour term is the HyAB distance of the two and the feature term the
        // absolute difference of their edge and point responses.
        let (fab, fba) = (flip(&a, &b, 67.0).unwrap(), flip(&b, &a, 67.0).unwrap());
        assert!(fab > 0.05 && (fab - fba).abs() < 1e-6, "{fab} {fba}");
    }

    #[test]
    fn nan_and_inf_are_counted_and_skipped() {
        let r = LinearImage::new(2, 1, vec![[0.5; 3], [0.5, f32::INFINITY, 0.5]]).unwrap();
        let t = LinearImage::new(2, 1, vec![[f32::NAN, 0.5, 0.5], [0.5, 0.5, f32::NEG_INFINITY]]).unwrap();
        let e = errors(&r, &t).unwrap();
        assert_eq!(e.reference_nonfinite, NonFinite { nan: 0, inf: 1 });
        assert_eq!(e.test_nonfinite, NonFinite { nan: 1, inf: 1 });
        assert_eq!(e.skipped_values, 3);
        assert_eq!((e.rmse, e.relmse, e.mae), (0.0, 0.0, 0.0), "the three finite pairs agree");
        assert!(e.flip.is_finite());
    }

    #[test]
    fn different_sizes_are_an_error() {
        let a = img(4, 4, |_, _| [0.0; 3]);
        let b = img(4, 5, |_, _| [0.0; 3]);
        let msg = errors(&a, &b).unwrap_err().to_string();
        assert!(msg.contains("4x4") && msg.contains("4x5"), "{msg}");
    }

    #[test]
    fn flip_grows_with_the_error() {
        let r = img(32, 32, |x, y| [((x / 4 + y / 4) % 2) as f32 * 0.8; 3]);
        let f = |a: f32| {
            flip(
                &r,
                &img(32, 32, |x, y| {
                    r.pixels[(y * 32 + x) as usize].map(|c| c + a * (((x * 7 + y * 13) % 5) as f32 / 5.0 - 0.4))
                }),
                67.0,
            )
            .unwrap()
        };
        let (f1, f2, f3) = (f(0.02), f(0.1), f(0.4));
        assert!(0.0 < f1 && f1 < f2 && f2 < f3 && f3 <= 1.0, "{f1} {f2} {f3}");
    }

    #[test]
    fn sidak_level() {
        assert!((sidak_alpha(0.01, 1) - 0.01).abs() < 1e-15);
        // 1 − 0.99^(1/1000) = 1.00503e-5.
        assert!((sidak_alpha(0.01, 1000) / 1.005_029_2e-5 - 1.0).abs() < 1e-6);
        // m tests at the Šidák level reject nothing with probability exactly 1 − α.
        let a = sidak_alpha(0.05, 3072);
        assert!(((1.0 - a).powi(3072) - 0.95).abs() < 1e-12);
    }

    #[test]
    fn mean_test_p_values() {
        // t = 2 with 1e9 samples: the normal two-sided tail 2·(1 − Φ(2)) = 0.0455003.
        let p = mean_test(0.0, 2.0, 1e9, 1_000_000_000).unwrap();
        assert!((p - 0.045_500_26).abs() < 1e-6, "{p}");
        // t = 2.262 with 10 samples (9 dof) is the two-sided 5% point of Student's t.
        let p = mean_test(1.0, 1.0 + 2.262157 * (0.4f64 / 10.0).sqrt(), 0.4, 10).unwrap();
        assert!((p - 0.05).abs() < 1e-5, "{p}");
        // Symmetric in the sign of the deviation.
        assert_eq!(mean_test(1.0, 1.3, 0.5, 20), mean_test(1.0, 0.7, 0.5, 20));
        assert_eq!(mean_test(1.0, 1.0, 0.0, 5), Some(1.0));
        assert_eq!(mean_test(1.0, 1.1, 0.0, 5), Some(0.0));
        assert_eq!(mean_test(1.0, f64::NAN, 0.1, 5), Some(0.0));
        assert_eq!(mean_test(1.0, 1.0, 0.1, 1), None);
    }

    /// Exact means pass, and a shift of a few standard errors in one pixel fails, on a 32×32
    /// image with normal-looking statistics drawn from a fixed generator.
    #[test]
    fn pixel_test_accepts_consistent_and_rejects_biased_stats() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let (w, h, n) = (32u32, 32u32, 64u64);
        let reference = img(w, h, |x, y| [0.1 + x as f32 / 32.0, 0.5, 0.2 + y as f32 / 64.0]);
        // Each pixel's mean of n samples uniform in r ± 0.5: variance 1/12 per sample.
        let mut means = reference.clone();
        for p in means.pixels.iter_mut() {
            for c in p.iter_mut() {
                *c += (0..n).map(|_| rng.random::<f32>() - 0.5).sum::<f32>() / n as f32;
            }
        }
        let stats = |mean: LinearImage| PixelStats {
            variance: img(w, h, |_, _| [1.0 / 12.0; 3]),
            count: vec![n; (w * h) as usize],
            mean,
        };
        let ok = pixel_test(&reference, &stats(means.clone()), 0.01).unwrap();
        assert!(ok.pass && ok.tests == 3072 && ok.rejected == 0, "{ok:?}");
        // One channel 8 standard errors off (σ/√n = 0.036): p ≈ 1e-11 < 3.3e-6.
        let mut biased = means;
        biased.pixels[5 * 32 + 9][1] += 8.0 * (1.0f32 / 12.0 / n as f32).sqrt();
        let bad = pixel_test(&reference, &stats(biased), 0.01).unwrap();
        assert!(!bad.pass && bad.rejected == 1 && bad.worst == Some((9, 5, 1)), "{bad:?}");
    }
}
