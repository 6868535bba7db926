//! The CPU reference renderer: rayon over tiles, each pixel through `shared::integrator`, the same
//! function the GPU kernel runs. Non-finite samples are zeroed and logged with their pixel.
use crate::render::{Compiled, Progress, RenderSettings, Rendered};
use anyhow::Result;
use rayon::prelude::*;
use shared::glam::Vec4;
use shared::integrator::render_pixel;
use std::sync::atomic::{AtomicU64, Ordering};

const TILE: u32 = 16;

pub fn render(c: &Compiled, s: &RenderSettings, progress: Progress) -> Result<Rendered> {
    s.check()?;
    let s = &RenderSettings { traversal: s.traversal.resolve(true), ..*s };
    let params = c.params(s, 0, s.spp)?;
    let scene = c.view(&params);
    let (w, h) = (s.width, s.height);
    let tiles_x = w.div_ceil(TILE);
    let tiles: Vec<(u32, u32)> = (0..h.div_ceil(TILE)).flat_map(|ty| (0..tiles_x).map(move |tx| (tx, ty))).collect();
    let total = w as u64 * h as u64 * s.spp as u64;
    let done = AtomicU64::new(0);
    let rendered: Vec<(u32, u32, Vec<(Vec4, u32)>)> = tiles
        .par_iter()
        .map(|&(tx, ty)| {
            let mut out = Vec::with_capacity((TILE * TILE) as usize);
            for y in ty * TILE..((ty + 1) * TILE).min(h) {
                for x in tx * TILE..((tx + 1) * TILE).min(w) {
                    let pass = render_pixel(&scene, &params, x, y, Vec4::ZERO);
                    if pass.sum.w > 0.0 {
                        eprintln!("warning: pixel ({x}, {y}): {} non-finite or negative sample(s) zeroed", pass.sum.w);
                    }
                    out.push((pass.sum, pass.primary));
                }
            }
            let n = out.len() as u64 * s.spp as u64;
            progress(done.fetch_add(n, Ordering::Relaxed) + n, total);
            (tx, ty, out)
        })
        .collect();
    let mut sum = vec![Vec4::ZERO; (w * h) as usize];
    let mut primary = vec![0u32; (w * h) as usize];
    for (tx, ty, out) in rendered {
        let mut k = 0;
        for y in ty * TILE..((ty + 1) * TILE).min(h) {
            for x in tx * TILE..((tx + 1) * TILE).min(w) {
                let i = (y * w + x) as usize;
                sum[i] = out[k].0;
                primary[i] = out[k].1;
                k += 1;
            }
        }
    }
    Ok(Rendered { width: w, height: h, spp: s.spp, sum, primary, traversal: s.traversal })
}
