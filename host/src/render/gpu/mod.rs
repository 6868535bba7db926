//! The GPU renderer: the rust-gpu kernel (`kernel/`, compiled by `build.rs`) run through wgpu.
//!
//! Each pass dispatches one invocation per pixel that adds a few samples to the pixel's running
//! sum in a storage buffer, so progress can be reported between passes and no single dispatch
//! runs long enough to trip a driver watchdog. The sums hold one block of samples at a time
//! (`blocks`): cleared at a block's start, read back at its end into the host's fold. Where the
//! connections draw from the pool of light subpaths, a dispatch of `trace_pool` first traces
//! the pools of the blocks of samples the next dispatch draws from (`pool`).
use crate::render::blocks::{Node, Sums, BLOCK_SAMPLES};
use crate::render::progressive::{Blocks, Progressive, RunningSums};
use crate::render::{Compiled, Progress, Rendered};
use crate::settings::{Dispatch, RenderSettings};
use anyhow::{anyhow, bail, Context, Result};
use shared::features::Variant;
use shared::glam::Vec4;
use shared::layout::{
    binding, RayQuery, RayResult, RenderParams, TriBlock, TriangleAttributes, CAST_GROUP, LIST_GROUP, PERSISTENT_GROUP,
    RENDER_GROUP_SIDE,
};
use std::collections::HashMap;
use std::sync::Mutex;
use wgpu::util::DeviceExt;

mod pool;
mod running;
use pool::GpuPool;
use running::GpuPasses;
pub use running::GpuProgressive;
pub(crate) use running::GpuSums;

static KERNEL_SPV: &[u8] = include_bytes!(env!("kernel.spv"));
const RENDER_ENTRY: &str = "render_pass";
const CAST_ENTRY: &str = "cast_rays";
const PERSISTENT_ENTRY: &str = "render_persistent";
const LIST_ENTRY: &str = "render_list";
const POOL_ENTRY: &str = "trace_pool";
/// Workgroups of the persistent kernel: enough to fill a large GPU (132 SMs × 16 groups of 64
/// on an H100 is about 2000), few enough that each takes many batches on smaller ones.
const PERSISTENT_GROUPS: u32 = 2048;
/// Vulkan guarantees at least this many workgroups per dispatch dimension.
const MAX_GROUPS_X: u32 = 65535;
/// Samples per pixel added in one dispatch are chosen so a pass traces about this many paths.
const PATHS_PER_PASS: u64 = 1 << 18;
/// lavapipe (llvmpipe's gallivm) ends every loop of a shader invocation once the invocation has
/// run 65535 loop iterations in all (`LP_MAX_TGSI_LOOP_ITERATIONS`, one counter shared by all
/// loops), silently: the traversal loops of later samples then stop at once and whole subgroups
/// lose those samples. A k-d traversal iterates once per node and per triangle, so on CPU
/// adapters the work of one invocation in one dispatch is kept small: at most this many samples
/// per pixel per pass (16 samples of 6-bounce paths in CornellBox-Water exceeded the limit; see
/// `tests/cpu_gpu_agreement.rs::water_box_agrees_with_many_samples_per_pixel`)...
const CPU_ADAPTER_SAMPLES_PER_PASS: u32 = 4;
/// ...and, for the persistent kernel, one sample per pass and at most this many batches per
/// workgroup. Real GPUs have no such limit.
const CPU_ADAPTER_PERSISTENT_ROUNDS: u32 = 4;
/// Adaptive sampling on a real GPU: at most this many samples per pixel and pass.
const GPU_ADAPTIVE_PASS_SAMPLES: u32 = 16;
/// Adaptive sampling: the pools of at most this many blocks at once (about 14 MB); a pass whose
/// pixels' samples span more blocks takes a dispatch per window of this many.
const ADAPTIVE_POOL_BLOCKS: u32 = 64;

pub struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
    module: wgpu::ShaderModule,
    layout: wgpu::PipelineLayout,
    // Each entry point is compiled when first used, once per variant (specialisation
    // constants): a driver compiles the whole integrator per pipeline, and a render needs one.
    pipelines: Mutex<HashMap<(&'static str, Variant), wgpu::ComputePipeline>>,
    bind_layout: wgpu::BindGroupLayout,
    pub adapter: wgpu::AdapterInfo,
}

/// One explicit layout for every entry point. wgpu's automatic layout keeps only the bindings an
/// entry point uses, so entry points that use different buffers could not share bind groups.
fn bind_group_layout_entries() -> Vec<wgpu::BindGroupLayoutEntry> {
    (0..binding::COUNT)
        .map(|b| wgpu::BindGroupLayoutEntry {
            binding: b,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                // The parameters too (`binding::PARAMS`: lavapipe recompiles for new uniforms).
                ty: wgpu::BufferBindingType::Storage { read_only: !binding::WRITABLE.contains(&b) },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        })
        .collect()
}

/// The scene's buffers on the device (bindings 0 to 6, 13, 15 and 16).
struct SceneBuffers {
    attributes: wgpu::Buffer,
    textures: wgpu::Buffer,
    params: wgpu::Buffer,
    nodes: wgpu::Buffer,
    indices: wgpu::Buffer,
    triangles: wgpu::Buffer,
    info: wgpu::Buffer,
    materials: wgpu::Buffer,
    lights: wgpu::Buffer,
    blocks: wgpu::Buffer,
}

fn instance() -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    desc.backends = wgpu::Backends::PRIMARY;
    wgpu::Instance::new(desc)
}

/// Every adapter wgpu can see (Vulkan, Metal, DX12), lavapipe included.
pub fn adapters() -> Vec<wgpu::AdapterInfo> {
    pollster::block_on(instance().enumerate_adapters(wgpu::Backends::PRIMARY)).iter().map(|a| a.get_info()).collect()
}

/// What Mesa's lavapipe calls itself (`llvmpipe (LLVM …)`): the one adapter on which the GPU
/// kernel's images equal the CPU path's bit for bit (it neither fuses multiply-adds nor rounds
/// division differently).
pub const LAVAPIPE: &str = "llvmpipe";

impl Gpu {
    /// Opens lavapipe by name, for the checks that promise bit-identity with the CPU path; an
    /// error (not another adapter) where it is not installed.
    pub fn lavapipe() -> Result<Self> {
        Self::open(Some(LAVAPIPE)).context(
            "the bit-exact CPU/GPU checks need Mesa's lavapipe (scripts/setup.sh installs mesa-vulkan-drivers)",
        )
    }

    /// Whether this adapter is lavapipe, where CPU and GPU results are bit-identical.
    pub fn is_lavapipe(&self) -> bool {
        self.adapter.name.to_lowercase().contains(LAVAPIPE)
    }

    /// Opens the first adapter whose name contains `name` (case-insensitive), or the first one.
    pub fn open(name: Option<&str>) -> Result<Self> {
        let all = pollster::block_on(instance().enumerate_adapters(wgpu::Backends::PRIMARY));
        let names: Vec<String> = all.iter().map(|a| a.get_info().name).collect();
        let adapter = match name {
            Some(n) => {
                let wanted = n.to_lowercase();
                all.into_iter()
                    .find(|a| a.get_info().name.to_lowercase().contains(&wanted))
                    .ok_or_else(|| anyhow!("no GPU adapter matches {n:?}; found {names:?}"))?
            }
            None => all.into_iter().next().ok_or_else(|| {
                anyhow!(
                    "no GPU adapter found (Vulkan, Metal or DX12). On Linux without a GPU, install Mesa's \
                     lavapipe: apt-get install mesa-vulkan-drivers libvulkan1"
                )
            })?,
        };
        Self::from_adapter(adapter)
    }

    /// Opens adapter `i` of `adapters()`'s list.
    pub fn open_index(i: usize) -> Result<Self> {
        let all = pollster::block_on(instance().enumerate_adapters(wgpu::Backends::PRIMARY));
        let n = all.len();
        let adapter =
            all.into_iter().nth(i).ok_or_else(|| anyhow!("no GPU adapter {i}: there are {n} (`kdtrace adapters`)"))?;
        Self::from_adapter(adapter)
    }

    fn from_adapter(adapter: wgpu::Adapter) -> Result<Self> {
        let info = adapter.get_info();
        let limits = adapter.limits();
        let storage = binding::COUNT;
        if limits.max_storage_buffers_per_shader_stage < storage {
            bail!(
                "adapter {:?} allows {} storage buffers per stage; the kernel needs {storage}",
                info.name,
                limits.max_storage_buffers_per_shader_stage
            );
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("kdtrace"),
            required_features: wgpu::Features::empty(),
            required_limits: limits,
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .with_context(|| format!("opening adapter {:?}", info.name))?;
        // Validation errors become an `Err` here instead of wgpu's default panic.
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("kernel"),
            source: wgpu::util::make_spirv(KERNEL_SPV),
        });
        let bind_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("scene"),
            entries: &bind_group_layout_entries(),
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("scene"),
            bind_group_layouts: &[Some(&bind_layout)],
            immediate_size: 0,
        });
        if let Some(e) = pollster::block_on(scope.pop()) {
            bail!("adapter {:?} rejected the kernel: {e}", info.name);
        }
        Ok(Self { device, queue, module, layout, pipelines: Mutex::new(HashMap::new()), bind_layout, adapter: info })
    }

    /// Compiles the render pipeline that `render(c, s)` will use now, so that it is not timed as
    /// rendering.
    pub fn prepare(&self, c: &Compiled, s: &RenderSettings) -> Result<()> {
        let entry = if s.adaptive.is_some() {
            LIST_ENTRY
        } else {
            match s.dispatch {
                Dispatch::Plain => RENDER_ENTRY,
                Dispatch::Persistent => PERSISTENT_ENTRY,
            }
        };
        self.pipeline(entry, variant(c, s))?;
        if c.params(s, 0, 0)?.light_pool != 0 {
            self.pipeline(POOL_ENTRY, Variant::GENERIC_SPEC)?;
        }
        Ok(())
    }

    /// The pipeline of kernel entry point `entry` specialised as `v`, compiled on first use.
    fn pipeline(&self, entry: &'static str, v: Variant) -> Result<wgpu::ComputePipeline> {
        if let Some(p) = self.pipelines.lock().unwrap().get(&(entry, v)) {
            return Ok(p.clone());
        }
        // Only what differs from the kernel's defaults: the generic pipeline sets nothing.
        let keys: Vec<(String, f64)> = v
            .spec_constants()
            .into_iter()
            .zip(Variant::GENERIC_SPEC.spec_constants())
            .filter(|(c, default)| c != default)
            .map(|((id, value), _)| (id.to_string(), value as f64))
            .collect();
        let constants: Vec<(&str, f64)> = keys.iter().map(|(id, value)| (id.as_str(), *value)).collect();
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let pipeline = self.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(entry),
            layout: Some(&self.layout),
            module: &self.module,
            entry_point: Some(entry),
            compilation_options: wgpu::PipelineCompilationOptions { constants: &constants, ..Default::default() },
            cache: None,
        });
        if let Some(e) = pollster::block_on(scope.pop()) {
            bail!("adapter {:?} rejected kernel entry point {entry} ({v:?}): {e}", self.adapter.name);
        }
        self.pipelines.lock().unwrap().insert((entry, v), pipeline.clone());
        Ok(pipeline)
    }

    /// Whether the adapter runs on the CPU (lavapipe, WARP): its limits and speeds differ.
    pub fn is_cpu(&self) -> bool {
        self.adapter.device_type == wgpu::DeviceType::Cpu
    }

    fn storage(&self, label: &str, data: &[u8]) -> wgpu::Buffer {
        self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: data,
            usage: wgpu::BufferUsages::STORAGE,
        })
    }

    /// A read-write buffer of `size` bytes that can be copied out; at least 16 bytes, since
    /// storage buffers may not be empty.
    fn output(&self, label: &str, size: u64) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: size.max(16),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    fn check_size(&self, what: &str, bytes: usize) -> Result<()> {
        let limit = self.device.limits().max_storage_buffer_binding_size;
        if bytes as u64 > limit {
            bail!("{what}: {bytes} bytes exceed this adapter's storage-buffer limit of {limit} bytes");
        }
        Ok(())
    }

    fn upload_scene(&self, c: &Compiled) -> Result<SceneBuffers> {
        self.check_size("triangles", std::mem::size_of_val(&c.scene.triangles[..]))?;
        self.check_size("k-d nodes", std::mem::size_of_val(&c.tree().nodes[..]))?;
        self.check_size("leaf indices", std::mem::size_of_val(&c.tree().indices[..]))?;
        self.check_size("vertex attributes", std::mem::size_of_val(&c.scene.attributes[..]))?;
        self.check_size("textures", std::mem::size_of_val(&c.textures[..]))?;
        let params = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("params"),
            size: std::mem::size_of::<RenderParams>() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(SceneBuffers {
            params,
            nodes: self.storage("nodes", bytemuck::cast_slice(&c.tree().nodes)),
            // Storage buffers may not be empty: a tree always has a node, the rest get a zero word.
            indices: self.storage(
                "indices",
                bytemuck::cast_slice(if c.tree().indices.is_empty() { &[0u32][..] } else { &c.tree().indices }),
            ),
            triangles: self.storage("triangles", bytemuck::cast_slice(&c.scene.triangles)),
            info: self.storage("info", bytemuck::cast_slice(&c.scene.info)),
            materials: self.storage("materials", bytemuck::cast_slice(&c.scene.materials)),
            lights: self.storage("lights", bytemuck::cast_slice(&c.lights)),
            // The GPU's leaf test reads `triangles` one by one (`shared::kdtree::test_leaf`):
            // the blocks binding only holds a placeholder.
            blocks: self.storage("blocks", bytemuck::bytes_of(&TriBlock::default())),
            // Without attributes or textures, a zero entry: `shared::surface` reads a triangle
            // beyond the attributes as having none, and no material names a texture.
            attributes: if c.scene.attributes.is_empty() {
                self.storage("attributes", bytemuck::bytes_of(&TriangleAttributes::default()))
            } else {
                self.storage("attributes", bytemuck::cast_slice(&c.scene.attributes))
            },
            textures: self.storage(
                "textures",
                bytemuck::cast_slice(if c.textures.is_empty() { &[0u32; 4][..] } else { &c.textures }),
            ),
        })
    }

    /// The bind group of all bindings: the scene's, then the outputs and ray buffers.
    #[allow(clippy::too_many_arguments)]
    fn bind(
        &self,
        s: &SceneBuffers,
        accum: &wgpu::Buffer,
        primary: &wgpu::Buffer,
        rays: &wgpu::Buffer,
        results: &wgpu::Buffer,
        queue: &wgpu::Buffer,
        accum_sq: &wgpu::Buffer,
        live: &wgpu::Buffer,
        pool: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        let buffers = [
            (binding::PARAMS, &s.params),
            (binding::NODES, &s.nodes),
            (binding::INDICES, &s.indices),
            (binding::TRIANGLES, &s.triangles),
            (binding::INFO, &s.info),
            (binding::MATERIALS, &s.materials),
            (binding::LIGHTS, &s.lights),
            (binding::ACCUM, accum),
            (binding::PRIMARY, primary),
            (binding::RAYS, rays),
            (binding::RESULTS, results),
            (binding::QUEUE, queue),
            (binding::ACCUM_SQ, accum_sq),
            (binding::BLOCKS, &s.blocks),
            (binding::LIVE, live),
            (binding::ATTRIBUTES, &s.attributes),
            (binding::TEXTURES, &s.textures),
            (binding::POOL, pool),
        ];
        debug_assert_eq!(buffers.len() as u32, binding::COUNT);
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .map(|&(binding, b)| wgpu::BindGroupEntry { binding, resource: b.as_entire_binding() })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("scene"),
            layout: &self.bind_layout,
            entries: &entries,
        })
    }

    fn dispatch(&self, pipeline: &wgpu::ComputePipeline, group: &wgpu::BindGroup, groups: (u32, u32)) -> Result<()> {
        let mut encoder = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("pass") });
        {
            let mut pass = encoder
                .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("compute"), timestamp_writes: None });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(groups.0, groups.1, 1);
        }
        self.queue.submit(Some(encoder.finish()));
        self.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| anyhow!("GPU pass failed: {e}"))?;
        Ok(())
    }

    /// The scene uploaded and the image's buffers created and bound, for a render of `s` (its
    /// traversal resolved) that draws from pools of `pool_blocks` blocks at once (0: none).
    fn allocate(&self, c: &Compiled, s: &RenderSettings, pool_blocks: u32) -> Result<ImageBuffers> {
        let pixels = s.width as u64 * s.height as u64;
        self.check_size("image", pixels as usize * 16)?;
        let scene = self.upload_scene(c)?;
        let accum_bytes = pixels * std::mem::size_of::<Vec4>() as u64;
        let accum = self.output("accum", accum_bytes);
        let accum_sq = self.output("accum squares", accum_bytes);
        let primary = self.output("primary", pixels * 4);
        let (rays, results) = (self.output("rays (unused)", 0), self.output("results (unused)", 0));
        let work = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("work queue"),
            size: 16,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let live = self.output("live pixels", if s.adaptive.is_some() { pixels * 16 } else { 0 });
        let pool = GpuPool::new(self, pool_blocks)?;
        let group = self.bind(&scene, &accum, &primary, &rays, &results, &work, &accum_sq, &live, &pool.buffer);
        Ok(ImageBuffers { scene, accum, accum_sq, primary, work, live, pool, group, pixels, accum_bytes })
    }

    pub fn render(&self, c: &Compiled, s: &RenderSettings, progress: Progress) -> Result<Rendered> {
        s.check()?;
        let s = &RenderSettings { traversal: s.traversal.for_adapter(self.is_cpu())?, ..*s };
        if let Some(a) = s.adaptive {
            let mut params = c.params(s, 0, 0)?;
            params.persistent_rounds = 0;
            let pool_blocks =
                if params.light_pool != 0 { GpuPool::blocks_for(s.spp).min(ADAPTIVE_POOL_BLOCKS) } else { 0 };
            let mut b = self.allocate(c, s, pool_blocks)?;
            let mut dev = GpuPasses {
                gpu: self,
                pipeline: self.pipeline(LIST_ENTRY, variant(c, s))?,
                group: &b.group,
                params,
                params_buffer: &b.scene.params,
                live: &b.live,
                pool: &mut b.pool,
                accum: &b.accum,
                bytes: b.accum_bytes,
            };
            let outcome = super::adaptive::render(&mut dev, s, a, progress)?;
            return Ok(Rendered {
                width: s.width,
                height: s.height,
                spp: s.spp,
                sum: self.read_back(&b.accum, b.accum_bytes)?,
                sum_sq: self.read_back(&b.accum_sq, b.accum_bytes)?,
                primary: self.read_back(&b.primary, b.pixels * 4)?,
                traversal: s.traversal,
                counts: Some(outcome.counts),
            });
        }
        let mut passes = self.progressive(c, s)?;
        let pixels = passes.sums.buffers.pixels;
        let total = pixels * s.spp as u64;
        let clock = std::time::Instant::now();
        let mut start = 0;
        while start < s.spp {
            // One dispatch a pass, so progress and the time limit are seen after each.
            let count = passes.per_dispatch().min(s.spp - start);
            passes.pass(start, count)?;
            start += count;
            progress(pixels * start as u64, total);
            // A time limit ends the render between passes: every pixel has `start` samples.
            if s.time_limit_s.is_some_and(|limit| clock.elapsed().as_secs_f64() >= limit) {
                break;
            }
        }
        passes.image()
    }

    /// Starts a progressive render of `c` with `s` on this adapter (`progressive::Progressive`):
    /// uploads the scene, creates and binds the image's buffers and compiles the pipeline
    /// (`s.dispatch`'s entry point, specialised for the scene). `s.spp` bounds the samples per
    /// dispatch (a pass takes as many dispatches as it needs); `s.time_limit_s` is the caller's to
    /// apply, and adaptive settings are refused.
    pub fn progressive<'a>(&'a self, c: &'a Compiled, s: &RenderSettings) -> Result<GpuProgressive<'a>> {
        let sums = self.sums(c, s)?;
        let blocks = Blocks::new(sums.buffers.pixels as usize);
        Ok(GpuProgressive { sums, blocks })
    }

    /// The running sums of one block on this adapter (`progressive::RunningSums`).
    pub(crate) fn sums<'a>(&'a self, c: &'a Compiled, s: &RenderSettings) -> Result<GpuSums<'a>> {
        s.check()?;
        if s.adaptive.is_some() {
            bail!("a progressive render adds the same samples to every pixel: adaptive sampling does not apply");
        }
        let s = RenderSettings { traversal: s.traversal.for_adapter(self.is_cpu())?, ..*s };
        let pixels = s.width as u64 * s.height as u64;
        // Work per invocation and dispatch, bounded on CPU adapters (see `CPU_ADAPTER_*`).
        let cpu_adapter = self.is_cpu();
        let batches = pixels.div_ceil(PERSISTENT_GROUP as u64) as u32;
        let (max_per_pass, rounds, persistent_groups) = match (s.dispatch, cpu_adapter) {
            (Dispatch::Persistent, true) => {
                (1, CPU_ADAPTER_PERSISTENT_ROUNDS, batches.div_ceil(CPU_ADAPTER_PERSISTENT_ROUNDS))
            }
            (Dispatch::Persistent, false) => (s.spp, u32::MAX, batches.min(PERSISTENT_GROUPS)),
            (Dispatch::Plain, true) => (CPU_ADAPTER_SAMPLES_PER_PASS, 0, 0),
            (Dispatch::Plain, false) => (s.spp, 0, 0),
        };
        let entry = match s.dispatch {
            Dispatch::Plain => RENDER_ENTRY,
            Dispatch::Persistent => PERSISTENT_ENTRY,
        };
        let pipeline = self.pipeline(entry, variant(c, &s))?;
        // A dispatch never crosses a block (`blocks`): more samples would be cut anyway.
        let per_dispatch =
            ((PATHS_PER_PASS / pixels.max(1)) as u32).clamp(1, s.spp.min(max_per_pass).min(BLOCK_SAMPLES));
        let params = c.params(&s, 0, 0)?;
        let pool_blocks = if params.light_pool != 0 { GpuPool::blocks_for(per_dispatch) } else { 0 };
        let buffers = self.allocate(c, &s, pool_blocks)?;
        Ok(GpuSums { gpu: self, s, params, buffers, pipeline, per_dispatch, rounds, persistent_groups })
    }

    /// Casts a batch of rays through the scene's tree (no shading); one result per ray.
    pub fn cast(&self, c: &Compiled, rays: &[RayQuery]) -> Result<Vec<RayResult>> {
        Ok(self.cast_timed(c, rays)?.0)
    }

    /// `cast`, with the seconds the dispatch took (from submission to completion; uploads and
    /// the read-back excluded).
    pub fn cast_timed(&self, c: &Compiled, rays: &[RayQuery]) -> Result<(Vec<RayResult>, f64)> {
        if rays.is_empty() {
            return Ok((Vec::new(), 0.0));
        }
        let bytes = std::mem::size_of_val(rays);
        self.check_size("rays", bytes)?;
        let scene = self.upload_scene(c)?;
        self.queue.write_buffer(&scene.params, 0, bytemuck::bytes_of(&c.bounds_params()));
        let ray_buffer = self.storage("rays", bytemuck::cast_slice(rays));
        let result_bytes = std::mem::size_of_val(rays) as u64 / std::mem::size_of::<RayQuery>() as u64
            * std::mem::size_of::<RayResult>() as u64;
        let results = self.output("results", result_bytes);
        let (accum, primary, work, accum_sq, live, pool) = (
            self.output("accum (unused)", 0),
            self.output("primary (unused)", 0),
            self.output("work queue (unused)", 0),
            self.output("accum squares (unused)", 0),
            self.output("live pixels (unused)", 0),
            self.output("light subpath pool (unused)", 0),
        );
        let group = self.bind(&scene, &accum, &primary, &ray_buffer, &results, &work, &accum_sq, &live, &pool);
        let groups = rays.len().div_ceil(CAST_GROUP as usize);
        if groups > MAX_GROUPS_X as usize {
            bail!("{} rays in one batch: at most {} are supported", rays.len(), MAX_GROUPS_X * CAST_GROUP);
        }
        let pipeline = &self.pipeline(CAST_ENTRY, Variant::GENERIC_SPEC)?;
        // Finish the uploads (and compile) first so the timing covers the dispatch alone.
        self.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| anyhow!("GPU upload failed: {e}"))?;
        let t = std::time::Instant::now();
        self.dispatch(pipeline, &group, (groups as u32, 1))?;
        let secs = t.elapsed().as_secs_f64();
        Ok((self.read_back(&results, result_bytes)?, secs))
    }

    fn read_back<T: bytemuck::Pod>(&self, src: &wgpu::Buffer, size: u64) -> Result<Vec<T>> {
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("staging"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder =
            self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("read back") });
        encoder.copy_buffer_to_buffer(src, 0, &staging, 0, size);
        self.queue.submit(Some(encoder.finish()));
        let slice = staging.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| anyhow!("GPU read-back failed: {e}"))?;
        rx.recv()?.map_err(|e| anyhow!("mapping the result buffer: {e}"))?;
        let data = slice.get_mapped_range().map_err(|e| anyhow!("mapping the result buffer: {e}"))?;
        let out = bytemuck::cast_slice::<u8, T>(&data).to_vec();
        drop(data);
        staging.unmap();
        Ok(out)
    }
}

/// The scene's buffers and the image's, bound (`Gpu::allocate`).
struct ImageBuffers {
    scene: SceneBuffers,
    accum: wgpu::Buffer,
    accum_sq: wgpu::Buffer,
    primary: wgpu::Buffer,
    /// The persistent kernel's work counter.
    work: wgpu::Buffer,
    /// Adaptive sampling's list of pixels (a placeholder otherwise).
    live: wgpu::Buffer,
    /// The pools of light subpaths the samples draw from (a placeholder without them).
    pool: GpuPool,
    group: wgpu::BindGroup,
    pixels: u64,
    accum_bytes: u64,
}

/// The specialisation constants of the pipeline that renders `c` with `s`: the scene's feature
/// set with the bounce limit and roulette start as constants, or the kernel's defaults (the
/// generic code) when specialisation is off.
pub fn variant(c: &Compiled, s: &RenderSettings) -> Variant {
    if s.specialize {
        Variant { features: super::features::variant_bits(c, s), max_bounces: s.max_bounces, rr_start: s.rr_start }
    } else {
        Variant::GENERIC_SPEC
    }
}

#[cfg(test)]
mod tests {
    use shared::features::Variant;
    use shared::layout::{binding, CAST_GROUP, LIST_GROUP, PERSISTENT_GROUP, POOL_GROUP, RENDER_GROUP_SIDE};

    /// The kernel's source, whose `#[spirv(...)]` attributes take literals only.
    const KERNEL: &str = include_str!("../../../../kernel/src/lib.rs");

    fn layout_binding(name: &str) -> u32 {
        match name {
            "params" => binding::PARAMS,
            "nodes" => binding::NODES,
            "indices" => binding::INDICES,
            "triangles" => binding::TRIANGLES,
            "info" => binding::INFO,
            "materials" => binding::MATERIALS,
            "lights" => binding::LIGHTS,
            "accum" => binding::ACCUM,
            "primary" => binding::PRIMARY,
            "rays" => binding::RAYS,
            "results" => binding::RESULTS,
            "queue" => binding::QUEUE,
            "accum_sq" => binding::ACCUM_SQ,
            "blocks" => binding::BLOCKS,
            "live" => binding::LIVE,
            "attributes" => binding::ATTRIBUTES,
            "textures" => binding::TEXTURES,
            "pool" => binding::POOL,
            other => panic!("kernel parameter {other:?} is not in shared::layout::binding"),
        }
    }

    #[test]
    fn kernel_bindings_match_the_layout() {
        let mut seen = 0;
        for line in KERNEL.lines() {
            let Some(at) = line.find("binding = ") else { continue };
            let rest = &line[at + "binding = ".len()..];
            let number: u32 = rest[..rest.find(')').unwrap()].parse().unwrap();
            let name = rest[rest.find("] ").unwrap() + 2..rest.find(':').unwrap()].trim();
            assert_eq!(number, layout_binding(name), "kernel binds {name} at {number}");
            assert!(number < binding::COUNT);
            seen += 1;
        }
        assert!(seen >= 5 * 10, "expected the five entry points' bindings, found {seen}");
        // Workgroup sizes: each entry point's `threads(...)` and the layout's constants.
        let threads = |entry: &str| {
            let at = KERNEL.find(&format!("pub fn {entry}(")).unwrap();
            let attr = KERNEL[..at].rfind("threads(").unwrap();
            let dims = &KERNEL[attr + "threads(".len()..];
            let dims: Vec<u32> =
                dims[..dims.find(')').unwrap()].split(',').map(|d| d.trim().parse().unwrap()).collect();
            dims
        };
        assert_eq!(threads("render_pass"), [RENDER_GROUP_SIDE, RENDER_GROUP_SIDE, 1]);
        assert_eq!(threads("render_persistent"), [PERSISTENT_GROUP, 1, 1]);
        assert_eq!(threads("cast_rays"), [CAST_GROUP, 1, 1]);
        assert_eq!(threads("render_list"), [LIST_GROUP, 1, 1]);
        assert_eq!(threads("trace_pool"), [POOL_GROUP, 1, 1]);
    }

    #[test]
    fn kernel_spec_constants_match_the_layout() {
        // The kernel's parameter names, in the order of `Variant::spec_constants`.
        let [f, b, r] = Variant::GENERIC_SPEC.spec_constants();
        let expected = [("features", f.0, f.1), ("max_bounces", b.0, b.1), ("rr_start", r.0, r.1)];
        let mut seen = 0;
        for line in KERNEL.lines() {
            let Some(at) = line.find("spec_constant(id = ") else { continue };
            let rest = &line[at + "spec_constant(id = ".len()..];
            let id: u32 = rest[..rest.find(',').unwrap()].parse().unwrap();
            let default = &rest[rest.find("default = ").unwrap() + "default = ".len()..];
            let default: u32 = default[..default.find(')').unwrap()].parse().unwrap();
            let name = rest[rest.find("] ").unwrap() + 2..rest.find(':').unwrap()].trim();
            let &(_, want_id, want_default) =
                expected.iter().find(|e| e.0 == name).unwrap_or_else(|| panic!("unknown spec constant {name}"));
            assert_eq!((id, default), (want_id, want_default), "kernel spec constant {name}");
            seen += 1;
        }
        // Three constants on each of the three render entry points.
        assert_eq!(seen, 9);
    }
}
