//! The CPU reference renderer: rayon over rows, each pixel through `shared::integrator`, the same
//! function the GPU kernel runs. Non-finite samples are zeroed and logged with their pixel.
use crate::render::{Compiled, Progress, Rendered};
use crate::settings::RenderSettings;
use anyhow::Result;
use rayon::prelude::*;
use shared::glam::Vec4;
use shared::integrator::render_pixel;
use shared::layout::NO_HIT;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// With a time limit, each pass is sized to take about this long, so the render stops close to
/// its budget.
const PASS_SECONDS: f64 = 0.25;

/// Renders on the CPU: rayon over image rows, every pixel through `shared::integrator`. Without a
/// time limit all samples are one pass; with one, passes of whole samples for every pixel run
/// until the budget is spent, so every pixel has the same number of samples (unbiased).
pub fn render(c: &Compiled, s: &RenderSettings, progress: Progress) -> Result<Rendered> {
    s.check()?;
    let s = &RenderSettings { traversal: s.traversal.resolve(true), ..*s };
    let (w, h) = (s.width, s.height);
    let n = (w * h) as usize;
    let mut sum = vec![Vec4::ZERO; n];
    let mut sum_sq = vec![Vec4::ZERO; n];
    let mut primary = vec![NO_HIT; n];
    let total = w as u64 * h as u64 * s.spp as u64;
    let done = AtomicU64::new(0);
    let clock = Instant::now();
    let mut start = 0u32;
    let mut count = if s.time_limit_s.is_some() { 1 } else { s.spp };
    while start < s.spp {
        count = count.min(s.spp - start);
        let params = c.params(s, start, count)?;
        let scene = c.view(&params);
        let pass_clock = Instant::now();
        sum.par_chunks_mut(w as usize)
            .zip(sum_sq.par_chunks_mut(w as usize))
            .zip(primary.par_chunks_mut(w as usize))
            .enumerate()
            .for_each(|(y, ((sum, sum_sq), primary))| {
                for x in 0..w as usize {
                    let before = sum[x].w;
                    render_pixel(&scene, &params, x as u32, y as u32, &mut sum[x], &mut sum_sq[x], &mut primary[x]);
                    if sum[x].w > before {
                        eprintln!(
                            "warning: pixel ({x}, {y}): {} non-finite or negative sample(s) zeroed",
                            sum[x].w - before
                        );
                    }
                }
                let k = w as u64 * count as u64;
                progress(done.fetch_add(k, Ordering::Relaxed) + k, total);
            });
        start += count;
        if let Some(limit) = s.time_limit_s {
            let elapsed = clock.elapsed().as_secs_f64();
            if elapsed >= limit {
                break;
            }
            // Size the next pass from this one's speed, within what is left of the budget.
            let per_sample = pass_clock.elapsed().as_secs_f64() / count as f64;
            let fit = (PASS_SECONDS.min(limit - elapsed) / per_sample.max(1e-9)).floor();
            count = (fit as u32).max(1);
        }
    }
    Ok(Rendered { width: w, height: h, spp: start, sum, sum_sq, primary, traversal: s.traversal })
}
