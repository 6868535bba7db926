//! A render in progress on a GPU: one block's running sums on the device (`GpuSums`, for the
//! shared block driver `progressive::Blocks`), the progressive render built on them
//! (`GpuProgressive`) and adaptive sampling's passes (`GpuPasses`).
use super::*;
use crate::render::adaptive::sample_span;
use crate::render::light_pool;
use shared::connection::POOL_SAMPLES;

/// One block's running sums on a GPU (`Gpu::sums`): the scene and the sums on the device, each
/// addition one or more dispatches.
pub(crate) struct GpuSums<'a> {
    pub(super) gpu: &'a Gpu,
    /// The settings, the traversal resolved for the adapter.
    pub(super) s: RenderSettings,
    /// `s`'s parameters, found once (`Compiled::params` analyses the scene); each dispatch sets
    /// its samples and rounds.
    pub(super) params: RenderParams,
    pub(super) buffers: ImageBuffers,
    pub(super) pipeline: wgpu::ComputePipeline,
    /// The most samples per pixel one dispatch adds (about `PATHS_PER_PASS` paths, at most
    /// `s.spp` and a block, within the CPU adapters' limits).
    pub(super) per_dispatch: u32,
    /// The persistent kernel's rounds per workgroup (`RenderParams::persistent_rounds`).
    pub(super) rounds: u32,
    pub(super) persistent_groups: u32,
}

impl RunningSums for GpuSums<'_> {
    fn zero(&mut self) -> Result<()> {
        let (g, b) = (self.gpu, &self.buffers);
        let mut encoder = g.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("zero") });
        encoder.clear_buffer(&b.accum, 0, None);
        encoder.clear_buffer(&b.accum_sq, 0, None);
        g.queue.submit(Some(encoder.finish()));
        Ok(())
    }

    fn add(&mut self, start: u32, count: u32) -> Result<()> {
        let (g, s, b) = (self.gpu, &self.s, &mut self.buffers);
        let end = start + count;
        let mut at = start;
        while at < end {
            let count = self.per_dispatch.min(end - at);
            let pool_first_block = if self.params.light_pool != 0 {
                let (first, blocks) = light_pool::span(at, at + count);
                b.pool.hold(g, &b.group, &b.scene.params, &self.params, first, blocks)?
            } else {
                0
            };
            let params = RenderParams {
                sample_start: at,
                sample_count: count,
                persistent_rounds: self.rounds,
                pool_first_block,
                ..self.params
            };
            g.queue.write_buffer(&b.scene.params, 0, bytemuck::bytes_of(&params));
            match s.dispatch {
                Dispatch::Plain => g.dispatch(
                    &self.pipeline,
                    &b.group,
                    (s.width.div_ceil(RENDER_GROUP_SIDE), s.height.div_ceil(RENDER_GROUP_SIDE)),
                )?,
                Dispatch::Persistent => {
                    g.queue.write_buffer(&b.work, 0, bytemuck::bytes_of(&[0u32; 4]));
                    g.dispatch(&self.pipeline, &b.group, (self.persistent_groups, 1))?
                }
            }
            at += count;
        }
        Ok(())
    }

    fn read(&mut self) -> Result<Sums> {
        let (g, b) = (self.gpu, &self.buffers);
        Ok(Sums { sum: g.read_back(&b.accum, b.accum_bytes)?, sum_sq: g.read_back(&b.accum_sq, b.accum_bytes)? })
    }

    fn primary(&mut self) -> Result<Vec<u32>> {
        let (g, b) = (self.gpu, &self.buffers);
        g.read_back(&b.primary, b.pixels * 4)
    }

    fn name(&self) -> String {
        self.gpu.adapter.name.clone()
    }
}

/// A render in progress on a GPU (`Gpu::progressive`): the running block's sums on the device,
/// the fold of the completed blocks on the host.
pub struct GpuProgressive<'a> {
    pub(super) sums: GpuSums<'a>,
    pub(super) blocks: Blocks,
}

impl GpuProgressive<'_> {
    /// The most samples per pixel one dispatch adds; a pass of more takes several dispatches.
    pub fn per_dispatch(&self) -> u32 {
        self.sums.per_dispatch
    }
}

impl Progressive for GpuProgressive<'_> {
    fn pass(&mut self, start: u32, count: u32) -> Result<()> {
        self.blocks.pass(&mut self.sums, start, count)
    }

    fn image(&mut self) -> Result<Rendered> {
        let sums = self.blocks.total(&mut self.sums)?;
        let primary = self.sums.primary()?;
        let s = &self.sums.s;
        Ok(Rendered {
            width: s.width,
            height: s.height,
            spp: self.blocks.spp(),
            sum: sums.sum,
            sum_sq: sums.sum_sq,
            primary,
            traversal: s.traversal,
            counts: None,
        })
    }

    fn spp(&self) -> u32 {
        self.blocks.spp()
    }

    fn device(&self) -> String {
        self.sums.name()
    }

    fn start_at(&mut self, start: u32) -> Result<()> {
        self.blocks.start_at(start)
    }

    fn nodes(&mut self) -> Result<Vec<Node>> {
        self.blocks.nodes(&mut self.sums)
    }
}

/// Adaptive sampling's passes on the GPU: each pass uploads the compacted list of pixels that
/// take samples and dispatches `render_list` over it.
pub(super) struct GpuPasses<'a> {
    pub(super) gpu: &'a Gpu,
    pub(super) pipeline: wgpu::ComputePipeline,
    pub(super) group: &'a wgpu::BindGroup,
    pub(super) params: RenderParams,
    pub(super) params_buffer: &'a wgpu::Buffer,
    pub(super) live: &'a wgpu::Buffer,
    pub(super) pool: &'a mut GpuPool,
    pub(super) accum: &'a wgpu::Buffer,
    pub(super) bytes: u64,
}

impl GpuPasses<'_> {
    /// Dispatches `render_list` over pixel `x`'s samples `y .. y + z` for each entry of `list`.
    fn dispatch(&mut self, list: &[[u32; 4]], pool_first_block: u32) -> Result<()> {
        let g = self.gpu;
        g.queue.write_buffer(self.live, 0, bytemuck::cast_slice(list));
        let params = RenderParams { live_count: list.len() as u32, pool_first_block, ..self.params };
        g.queue.write_buffer(self.params_buffer, 0, bytemuck::bytes_of(&params));
        let groups = (list.len() as u32).div_ceil(LIST_GROUP);
        let x = groups.min(MAX_GROUPS_X);
        g.dispatch(&self.pipeline, self.group, (x, groups.div_ceil(x)))
    }
}

impl crate::render::adaptive::Passes for GpuPasses<'_> {
    fn pass(&mut self, ranges: &[[u32; 2]]) -> Result<()> {
        let list: Vec<[u32; 4]> = ranges
            .iter()
            .enumerate()
            .filter(|(_, r)| r[1] > 0)
            .map(|(pixel, &[start, count])| [pixel as u32, start, count, 0])
            .collect();
        if list.is_empty() {
            return Ok(());
        }
        if self.params.light_pool == 0 {
            return self.dispatch(&list, 0);
        }
        // The samples' pools in windows of blocks the pool buffer holds, each window a dispatch
        // of the pixels' samples in it: a pixel's samples still add up in order.
        let samples = |list: &[[u32; 4]]| sample_span(list.iter().map(|e| [e[1], e[2]]));
        let (start, end) = samples(&list);
        let (first, blocks) = light_pool::span(start, end);
        let window = self.pool.capacity();
        for w in (first..first + blocks).step_by(window as usize) {
            let (lo, hi) = (w * POOL_SAMPLES, (w + window) * POOL_SAMPLES);
            let part: Vec<[u32; 4]> = list
                .iter()
                .filter(|e| e[1] < hi && e[1] + e[2] > lo)
                .map(|e| {
                    let (a, b) = (e[1].max(lo), (e[1] + e[2]).min(hi));
                    [e[0], a, b - a, 0]
                })
                .collect();
            if part.is_empty() {
                continue;
            }
            let (part_start, part_end) = samples(&part);
            let (at, n) = light_pool::span(part_start, part_end);
            let held = self.pool.hold(self.gpu, self.group, self.params_buffer, &self.params, at, n)?;
            self.dispatch(&part, held)?;
        }
        Ok(())
    }

    fn max_per_pass(&self) -> u32 {
        if self.gpu.is_cpu() {
            CPU_ADAPTER_SAMPLES_PER_PASS
        } else {
            GPU_ADAPTIVE_PASS_SAMPLES
        }
    }

    fn sums(&mut self) -> Result<Vec<Vec4>> {
        self.gpu.read_back(self.accum, self.bytes)
    }
}
