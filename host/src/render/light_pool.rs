//! The pools of light subpaths the CPU's connections draw from (`shared::connection::LightPool`):
//! `POOL_SLOTS` light subpaths for each block of `POOL_SAMPLES` samples, traced in parallel
//! before the samples that use them. A slot's subpath depends only on the seed, its block and
//! its index, so a sample draws from the same pool in any pass structure (progressive,
//! adaptive, two blocks at once, another process of a farm).
use crate::settings::RenderSettings;
use rayon::prelude::*;
use shared::connection::{pool_record, LightPool, POOL_RECORD, POOL_SAMPLES, POOL_SLOTS};
use shared::features::{Variant, FEATURES_ALL};
use shared::layout::RenderParams;
use shared::scene::SceneView;

/// `p` with the connections drawing from the pool of light subpaths where they run and `s`
/// asks for it (`RenderSettings::light_pool`).
pub fn pooled(p: RenderParams, s: &RenderSettings) -> RenderParams {
    RenderParams { light_pool: u32::from(s.light_pool && p.connect != 0), ..p }
}

/// The pools samples `[start, end)` draw from where `p` asks for them (`trace`), else none.
pub fn pool_of(scene: &SceneView, p: &RenderParams, start: u32, end: u32) -> (Vec<f32>, u32) {
    if p.light_pool != 0 {
        trace(scene, p, start, end)
    } else {
        (Vec::new(), 0)
    }
}

/// The pools of the blocks that samples `[start, end)` fall in (nothing for an empty range), and
/// the first block's index.
pub fn trace(scene: &SceneView, p: &RenderParams, start: u32, end: u32) -> (Vec<f32>, u32) {
    if end <= start {
        return (Vec::new(), 0);
    }
    let first = start / POOL_SAMPLES;
    let blocks = (end - 1) / POOL_SAMPLES + 1 - first;
    let v = Variant::new(FEATURES_ALL, p);
    let mut records = vec![0.0f32; blocks as usize * POOL_SLOTS as usize * POOL_RECORD];
    records.par_chunks_mut(POOL_RECORD * 256).enumerate().for_each(|(chunk, out)| {
        for (i, r) in out.as_chunks_mut::<POOL_RECORD>().0.iter_mut().enumerate() {
            let k = (chunk * 256 + i) as u32;
            *r = pool_record(scene, p, v, first + k / POOL_SLOTS, k % POOL_SLOTS);
        }
    });
    (records, first)
}

/// `scene` drawing from `records` (`trace`'s) whose first block is `first_block`.
pub fn view<'a>(scene: &SceneView<'a>, records: &'a [f32], first_block: u32) -> SceneView<'a> {
    SceneView { light_pool: LightPool { records, first_block }, ..*scene }
}
