//! The pools of light subpaths the CPU's connections draw from (`shared::connection::LightPool`):
//! `POOL_SLOTS` light subpaths for each block of `POOL_SAMPLES` samples, traced in parallel
//! before the samples that use them (a GPU traces the same ones with `trace_pool`). A slot's
//! subpath depends only on the seed, its block and its index, so a sample draws from the same
//! pool in any pass structure (progressive, adaptive, two blocks at once, another process of a
//! farm).
use rayon::prelude::*;
use shared::connection::{
    pool_record, store_pool_record, LightPool, POOL_BLOCK, POOL_FIELDS, POOL_SAMPLES, POOL_SLOTS,
};
use shared::layout::RenderParams;
use shared::scene::SceneView;

/// The pools samples `[start, end)` draw from where `p` asks for them (`trace`), else none.
pub fn pool_of(scene: &SceneView, p: &RenderParams, start: u32, end: u32) -> (Vec<f32>, u32) {
    if p.light_pool != 0 {
        trace(scene, p, start, end)
    } else {
        (Vec::new(), 0)
    }
}

/// The blocks that samples `[start, end)` (not empty) draw from: the first and how many.
pub fn span(start: u32, end: u32) -> (u32, u32) {
    let first = start / POOL_SAMPLES;
    (first, (end - 1) / POOL_SAMPLES + 1 - first)
}

/// The pools of the blocks that samples `[start, end)` fall in (nothing for an empty range), and
/// the first block's index.
pub fn trace(scene: &SceneView, p: &RenderParams, start: u32, end: u32) -> (Vec<f32>, u32) {
    if end <= start {
        return (Vec::new(), 0);
    }
    let (first, blocks) = span(start, end);
    let slots = POOL_SLOTS as usize;
    let mut records = vec![0.0f32; blocks as usize * POOL_BLOCK];
    // Each block's records traced in parallel, then written field by field as the GPU's
    // `trace_pool` stores them (slot `slot` of a one-block buffer).
    records.par_chunks_mut(POOL_BLOCK).enumerate().for_each(|(block, out)| {
        let block = first + block as u32;
        let mut columns = vec![[0.0f32; POOL_FIELDS]; slots];
        columns.par_iter_mut().enumerate().for_each(|(slot, r)| *r = pool_record(scene, p, block, slot as u32));
        for (slot, r) in columns.iter().enumerate() {
            store_pool_record(out, slot as u32, r);
        }
    });
    (records, first)
}

/// `scene` drawing from `records` (`trace`'s) whose first block is `first_block`.
pub fn view<'a>(scene: &SceneView<'a>, records: &'a [f32], first_block: u32) -> SceneView<'a> {
    SceneView { light_pool: LightPool { records, first_block }, ..*scene }
}
