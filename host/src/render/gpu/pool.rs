//! The pools of light subpaths on a GPU (`shared::connection::LightPool`): the `trace_pool`
//! entry point traces the blocks a dispatch's samples draw from into a buffer of a few blocks
//! (`binding::POOL`) before the dispatch, the same light subpaths the CPU's pools hold
//! (`render::light_pool`), so both devices render the same image.
use super::{Gpu, MAX_GROUPS_X, POOL_ENTRY};
use anyhow::Result;
use shared::connection::{POOL_BLOCK, POOL_SAMPLES, POOL_SLOTS};
use shared::features::Variant;
use shared::layout::{RenderParams, POOL_GROUP};

/// The pool buffer and the blocks it holds.
pub(super) struct GpuPool {
    pub(super) buffer: wgpu::Buffer,
    /// Blocks the buffer has room for (0: the render draws from no pool; a placeholder).
    capacity: u32,
    /// The blocks traced into it: the first and how many.
    held: Option<(u32, u32)>,
}

impl GpuPool {
    /// A buffer of `blocks` blocks' pools (none: a placeholder).
    pub(super) fn new(gpu: &Gpu, blocks: u32) -> Result<Self> {
        let bytes = blocks as usize * POOL_BLOCK * 4;
        gpu.check_size("light subpath pool", bytes)?;
        Ok(Self { buffer: gpu.output("light subpath pool", bytes as u64), capacity: blocks, held: None })
    }

    /// Blocks a dispatch of `count` samples per pixel from any sample can draw from.
    pub(super) fn blocks_for(count: u32) -> u32 {
        count.div_ceil(POOL_SAMPLES) + 1
    }

    /// Blocks the buffer has room for.
    pub(super) fn capacity(&self) -> u32 {
        self.capacity
    }

    /// Makes the buffer hold the pools of blocks `[first, first + count)` (at most `capacity`),
    /// tracing them unless it holds them already; `params` are the render's, `group` binds the
    /// buffer. Returns the block the buffer starts with (`RenderParams::pool_first_block`).
    pub(super) fn hold(
        &mut self,
        gpu: &Gpu,
        group: &wgpu::BindGroup,
        params_buffer: &wgpu::Buffer,
        params: &RenderParams,
        first: u32,
        count: u32,
    ) -> Result<u32> {
        debug_assert!(count <= self.capacity);
        if let Some((held, n)) = self.held {
            if held <= first && first + count <= held + n {
                return Ok(held);
            }
        }
        let trace = RenderParams { pool_first_block: first, sample_count: count, ..*params };
        gpu.queue.write_buffer(params_buffer, 0, bytemuck::bytes_of(&trace));
        let groups = count * (POOL_SLOTS / POOL_GROUP);
        let x = groups.min(MAX_GROUPS_X);
        gpu.dispatch(&gpu.pipeline(POOL_ENTRY, Variant::GENERIC_SPEC)?, group, (x, groups.div_ceil(x)))?;
        self.held = Some((first, count));
        Ok(first)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::light_pool;
    use crate::scene::procedural::furnace;
    use crate::settings::{camera::Camera, RenderSettings, Traversal};
    use shared::glam::DVec3;

    /// lavapipe's pools are the CPU's bit for bit, from any first block, and a block the buffer
    /// holds is not traced again.
    #[test]
    fn lavapipe_traces_the_cpus_pools() {
        let gpu = Gpu::lavapipe().unwrap();
        let c = crate::compile(furnace(0.5, 1.0).unwrap(), Default::default());
        let camera = Camera { eye: DVec3::new(0.0, 0.0, 0.5), target: DVec3::ZERO, up: DVec3::Y, fov_deg: 60.0 };
        let s = RenderSettings {
            width: 16,
            height: 16,
            max_bounces: 3,
            seed: 5,
            traversal: Traversal::Full,
            ..RenderSettings::with_camera(camera)
        };
        let b = gpu.allocate(&c, &s, 2).unwrap();
        let (group, params_buffer) = (&b.group, &b.scene.params);
        let mut pool = b.pool;
        let params = c.params(&s, 0, 0).unwrap();
        assert_eq!(params.light_pool, 1);
        for (first, count) in [(0, 1), (3, 2)] {
            assert_eq!(pool.hold(&gpu, group, params_buffer, &params, first, count).unwrap(), first);
            let got: Vec<f32> = gpu.read_back(&pool.buffer, (count as usize * POOL_BLOCK * 4) as u64).unwrap();
            let (want, at) =
                light_pool::trace(&c.view(&params), &params, first * POOL_SAMPLES, (first + count) * POOL_SAMPLES);
            assert_eq!(at, first);
            let valid = want.chunks(13).filter(|r| r.iter().any(|&x| x != 0.0)).count();
            assert!(valid > want.len() / 26, "few light subpaths reach a wall: {valid}");
            let same = got.iter().zip(&want).filter(|(a, b)| a.to_bits() == b.to_bits()).count();
            assert_eq!(
                same,
                want.len(),
                "blocks {first}..{}: {same} of {} floats bitwise equal",
                first + count,
                want.len()
            );
        }
        // Held: the second block of the last call is not traced again.
        assert_eq!(pool.hold(&gpu, group, params_buffer, &params, 4, 1).unwrap(), 3);
    }
}
