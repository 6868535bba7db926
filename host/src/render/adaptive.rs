//! Adaptive sampling: samples go to the pixels whose estimate is still noisy, on either device.
//!
//! Every pixel first gets `min_spp` pilot samples. From their sums each pixel's per-sample
//! relative variance v is estimated (per channel σ² / (mean² + 0.01), the form of `compare`'s
//! relMSE, averaged over channels), then averaged over the pixel's 5×5 neighbourhood. A variance
//! from a few samples of heavy-tailed path radiance is mostly noise: budgets from it alone were
//! no better than uniform sampling on `scenes/uneven-noise.toml`, and the box (variance changes
//! slowly across an image) brings them to within 15% of the budgets from the true variance. It
//! also keeps a pixel whose pilot missed a rare bright path that its neighbours caught from
//! being left behind (Cycles widens its convergence test over neighbours for that reason).
//! The image's relMSE with n_i samples per pixel is mean(v_i / n_i); for a given total it is smallest with n_i ∝ √v_i (a Lagrange
//! multiplier; the allocation of Neyman's optimal stratified sampling), and it equals the
//! threshold² with n_i = √v_i · mean(√v) / threshold². (Equal error per pixel, n_i ∝ v_i, would
//! spend as much as uniform sampling for the same mean error.) Then:
//! - `Pilot` (the default, unbiased) fixes each pixel's budget once, after the pilot, from its
//!   neighbours' estimates alone (the 5×5 box without the pixel itself), and the image averages
//!   all of the pixel's samples, pilot included. A count chosen from the very samples it then
//!   averages correlates with their values and biases the mean (Kirk & Arvo 1991, "Unbiased
//!   sampling techniques for image synthesis"); a count chosen from other pixels' independent
//!   samples does not, so nothing is thrown away and each pixel's samples stay the sequence's
//!   best-spread prefix [0, n).
//! - `AsYouGo` keeps every sample and, after each round, recomputes the budgets from all samples
//!   so far; the pixels below theirs go on (at most doubling per round), the others stop. Biased,
//!   as Kirk & Arvo show: README states by how much.
//!
//! The device only adds given sample ranges to given pixels (`Passes`): the CPU over its rows,
//! the GPU through a compacted list of live pixels (`kernel::render_list`). Each pixel's samples
//! are added in index order in either case, so the image does not depend on how passes are cut,
//! and the CPU and lavapipe agree bit for bit.
use crate::render::Progress;
use crate::settings::{Adaptive, AdaptiveMode, RenderSettings};
use anyhow::Result;
use shared::glam::Vec4;
use std::time::Instant;

/// The offset in the relative variance's denominator (`compare`'s relMSE uses the same), so
/// that black pixels do not demand samples without end.
const DARK: f64 = 0.01;
/// The radius of the box that averages the relative variance: 5×5 pixels.
const SMOOTHING: usize = 2;

/// What a device does for adaptive sampling.
pub trait Passes {
    /// Adds samples `[start, start + count)` to every pixel whose `ranges[pixel] = [start, count]`
    /// has `count > 0`, in index order.
    fn pass(&mut self, ranges: &[[u32; 2]]) -> Result<()>;
    /// The most samples one pixel may take in one pass.
    fn max_per_pass(&self) -> u32;
    /// The running radiance sums (with the zeroed-sample count in `w`): what the estimate needs.
    fn sums(&mut self) -> Result<Vec<Vec4>>;
}

/// The samples `[lo, hi)` that the non-empty `[start, count]` ranges of a pass cover (`(u32::MAX,
/// 0)` where all are empty).
pub fn sample_span(ranges: impl IntoIterator<Item = [u32; 2]>) -> (u32, u32) {
    ranges.into_iter().filter(|r| r[1] > 0).fold((u32::MAX, 0), |(lo, hi), r| (lo.min(r[0]), hi.max(r[0] + r[1])))
}

/// What an adaptive render leaves: per pixel the samples its sums hold.
pub struct Outcome {
    pub counts: Vec<u32>,
}

/// A pixel's per-sample relative variance from two disjoint runs of its samples, the first
/// `first_count` summing to `first`, all `count` to `all` (Cycles' half-buffer estimate): the two
/// runs' means differ by d, whose square has expectation σ²·(1/n₁ + 1/n₂). Unlike the samples'
/// own variance it sees how fast the mean actually converges, which with stratified (Sobol)
/// samples is faster than σ²/n where the integrand is smooth. Per channel σ² / (mean² + 0.01),
/// averaged over channels as relMSE averages them; 0 when either run is empty.
pub fn relative_variance(first: Vec4, first_count: u32, all: Vec4, count: u32) -> f64 {
    if first_count == 0 || first_count >= count {
        return 0.0;
    }
    let (n1, n2, n) = (first_count as f64, (count - first_count) as f64, count as f64);
    let channel = |f: f32, a: f32| {
        let (f, a) = (f as f64, a as f64);
        let d = f / n1 - (a - f) / n2;
        let mean = a / n;
        d * d / (1.0 / n1 + 1.0 / n2) / (mean * mean + DARK)
    };
    (channel(first.x, all.x) + channel(first.y, all.y) + channel(first.z, all.z)) / 3.0
}

/// Per pixel the latest raw estimate and the sums it will be split from next.
struct Estimator {
    raw: Vec<f64>,
    first: Vec<Vec4>,
    first_counts: Vec<u32>,
}

impl Estimator {
    fn new(n: usize) -> Self {
        Self { raw: vec![0.0; n], first: vec![Vec4::ZERO; n], first_counts: vec![0; n] }
    }

    /// Takes sums `sum` after `counts` samples: every pixel that has gained samples since the
    /// last call gets a new estimate from the two runs (before, since), and its sums become the
    /// next first run.
    fn update(&mut self, sum: &[Vec4], counts: &[u32]) {
        for i in 0..sum.len() {
            if counts[i] > self.first_counts[i] {
                if self.first_counts[i] > 0 {
                    self.raw[i] = relative_variance(self.first[i], self.first_counts[i], sum[i], counts[i]);
                }
                self.first[i] = sum[i];
                self.first_counts[i] = counts[i];
            }
        }
    }

    /// The smoothed estimates; without `own`, each pixel's from its neighbours' alone.
    fn estimates(&self, s: &RenderSettings, own: bool) -> Vec<f64> {
        smooth(&self.raw, s.width as usize, s.height as usize, own)
    }
}

/// `values` averaged over each pixel's (2·`SMOOTHING` + 1)² neighbourhood (clipped at the
/// image's edges).
/// Without `own`, each pixel's own value is left out of its average (its neighbours' alone).
fn smooth(values: &[f64], width: usize, height: usize, own: bool) -> Vec<f64> {
    let r = SMOOTHING;
    let mut out = vec![0.0; values.len()];
    for y in 0..height {
        for x in 0..width {
            let (mut sum, mut n) = (0.0, 0.0);
            for yy in y.saturating_sub(r)..(y + r + 1).min(height) {
                for xx in x.saturating_sub(r)..(x + r + 1).min(width) {
                    if own || (xx, yy) != (x, y) {
                        sum += values[yy * width + xx];
                        n += 1.0;
                    }
                }
            }
            out[y * width + x] = if n > 0.0 { sum / n } else { 0.0 };
        }
    }
    out
}

/// Per pixel the samples that bring the image's relMSE to `threshold`² from relative variances
/// `rv`: n_i = √v_i · mean(√v) / threshold², within [lo, hi].
fn budgets(rv: &[f64], threshold: f32, lo: u32, hi: u32) -> Vec<u32> {
    let t2 = threshold as f64 * threshold as f64;
    let mean_sqrt = mean_sqrt(rv);
    rv.iter()
        .map(|v| {
            let n = (v.sqrt() * mean_sqrt / t2).ceil();
            if n >= hi as f64 {
                hi
            } else {
                (n as u32).clamp(lo, hi)
            }
        })
        .collect()
}

/// mean(√v).
fn mean_sqrt(rv: &[f64]) -> f64 {
    rv.iter().map(|v| v.sqrt()).sum::<f64>() / rv.len().max(1) as f64
}

/// Renders adaptively on `dev`; the sums are left on the device, the counts returned.
pub fn render(dev: &mut impl Passes, s: &RenderSettings, a: Adaptive, progress: Progress) -> Result<Outcome> {
    let n = (s.width * s.height) as usize;
    let clock = Instant::now();
    let out_of_time = |clock: &Instant| s.time_limit_s.is_some_and(|limit| clock.elapsed().as_secs_f64() >= limit);
    let step = dev.max_per_pass().max(1);
    // The pilot: samples [0, min_spp) everywhere, in two halves for the estimate.
    let mut counts = vec![0u32; n];
    let mut estimator = Estimator::new(n);
    let pilot_total = n as u64 * a.min_spp as u64;
    for half in [a.min_spp / 2, a.min_spp] {
        run_ranges(dev, &mut counts, &vec![half; n], step, &|d| progress(d, pilot_total), &out_of_time, &clock)?;
        estimator.update(&dev.sums()?, &counts);
    }
    let pilot_s = clock.elapsed().as_secs_f64();
    match a.mode {
        AdaptiveMode::Pilot => {
            // Each pixel's budget from its neighbours' pilot samples alone, so that its count
            // does not depend on its own samples, which all stay in the image.
            let rv = estimator.estimates(s, false);
            let mut threshold = a.threshold;
            if let Some(limit) = s.time_limit_s {
                // Fit the budgets into the time left at the pilot's speed: the threshold whose
                // budgets (before clamping) sum to what the time allows, if that is above the
                // one asked for. The proportions stay, so the time goes where the noise is.
                let per_sample = pilot_s / pilot_total as f64;
                let allowed = (limit - pilot_s).max(0.0) / per_sample.max(1e-12);
                let m = mean_sqrt(&rv);
                let fitted = (n as f64 * m * m / allowed.max(1.0)).sqrt();
                threshold = threshold.max(fitted as f32);
            }
            let budget = budgets(&rv, threshold, a.min_spp, s.spp);
            let total: u64 = budget.iter().map(|&b| b as u64).sum();
            run_ranges(
                dev,
                &mut counts,
                &budget,
                step,
                &|done| progress(pilot_total + done, total),
                &out_of_time,
                &clock,
            )?;
            Ok(Outcome { counts })
        }
        AdaptiveMode::AsYouGo => {
            let mut rv = estimator.estimates(s, true);
            let mut done = pilot_total;
            loop {
                // A pixel below its budget goes on, at most doubling its samples this round.
                let target: Vec<u32> = budgets(&rv, a.threshold, a.min_spp, s.spp)
                    .iter()
                    .zip(&counts)
                    .map(|(&b, &c)| b.min(c * 2).max(c))
                    .collect();
                if target == counts || out_of_time(&clock) {
                    break;
                }
                let round: u64 = target.iter().zip(&counts).map(|(&t, &c)| (t - c) as u64).sum();
                let before = done;
                run_ranges(
                    dev,
                    &mut counts,
                    &target,
                    step,
                    &|d| progress(before + d, before + round),
                    &out_of_time,
                    &clock,
                )?;
                done += round;
                estimator.update(&dev.sums()?, &counts);
                rv = estimator.estimates(s, true);
            }
            Ok(Outcome { counts })
        }
    }
}

/// Passes until every pixel's `counts[i]` reaches `target[i]`, its next sample numbered
/// `counts[i]`, at most `step` per pixel and pass; stops early when out of time.
fn run_ranges(
    dev: &mut impl Passes,
    counts: &mut [u32],
    target: &[u32],
    step: u32,
    progress: &dyn Fn(u64),
    out_of_time: &dyn Fn(&Instant) -> bool,
    clock: &Instant,
) -> Result<()> {
    let start: Vec<u32> = counts.to_vec();
    loop {
        let ranges: Vec<[u32; 2]> =
            counts.iter().zip(target).map(|(&c, &t)| [c, t.saturating_sub(c).min(step)]).collect();
        if ranges.iter().all(|r| r[1] == 0) {
            return Ok(());
        }
        dev.pass(&ranges)?;
        for (c, r) in counts.iter_mut().zip(&ranges) {
            *c += r[1];
        }
        progress(counts.iter().zip(&start).map(|(&c, &s)| (c - s) as u64).sum());
        if out_of_time(clock) {
            return Ok(());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_variance_of_known_runs() {
        // Runs of means 1 (two samples) and 3 (two samples): d = 2, σ² = 4 / (1/2 + 1/2) = 4,
        // mean 2, so 4 / 4.01 in every channel.
        let (first, all) = (Vec4::new(2.0, 2.0, 2.0, 0.0), Vec4::new(8.0, 8.0, 8.0, 0.0));
        assert!((relative_variance(first, 2, all, 4) - 4.0 / 4.01).abs() < 1e-12);
        // Equal runs: no evidence of noise. An empty run: no estimate.
        assert_eq!(relative_variance(Vec4::splat(2.0), 2, Vec4::splat(4.0), 4), 0.0);
        assert_eq!(relative_variance(first, 4, all, 4), 0.0);
        assert_eq!(relative_variance(first, 0, all, 4), 0.0);
    }

    #[test]
    fn budgets_follow_the_square_root_of_the_variance() {
        // v = 0.04 and 0.16, mean √v = 0.3, t = 0.1: n = √v · 0.3 / 0.01 = 6 and 12.
        assert_eq!(budgets(&[0.04, 0.16], 0.1, 1, 64), [6, 12]);
        // The image's expected relMSE is then t²: (0.04/6 + 0.16/12) / 2 = 0.01.
        // A constant pixel gets the least, an infinite variance the most.
        // Mean √v = 0.2: 0.4 · 0.2 / 0.01 = 8 for the noisy pixel, the least for the other.
        assert_eq!(budgets(&[0.0, 0.16], 0.1, 2, 64), [2, 8]);
        assert_eq!(budgets(&[f64::INFINITY, 0.0], 0.1, 2, 64), [64, 2]);
    }

    #[test]
    fn smoothing_spreads_to_neighbours() {
        // A 7×7 image with one pixel of 25 in the middle reaches the 5×5 box around it.
        let mut v = vec![0.0; 49];
        v[24] = 25.0;
        let d = smooth(&v, 7, 7, true);
        let live: Vec<usize> = (0..49).filter(|&i| d[i] > 0.0).collect();
        let expected: Vec<usize> = (1..6).flat_map(|y| (1..6).map(move |x| y * 7 + x)).collect();
        assert_eq!(live, expected);
        // The middle pixel's box is whole; (1, 1)'s is clipped to 4×4.
        assert_eq!((d[24], d[8]), (1.0, 25.0 / 16.0));
        // Clipped at the edges: in a 2×2 image every box holds the 4 pixels.
        assert_eq!(smooth(&[9.0, 0.0, 0.0, 0.0], 2, 2, true), [2.25; 4]);
        // Without their own values: the other three pixels' mean.
        assert_eq!(smooth(&[9.0, 0.0, 0.0, 0.0], 2, 2, false), [0.0, 3.0, 3.0, 3.0]);
        assert_eq!(smooth(&[5.0], 1, 1, false), [0.0]);
    }
}
