//! The GPU renderer: the rust-gpu kernel (`kernel/`, compiled by `build.rs`) run through wgpu.
//!
//! Each pass dispatches one invocation per pixel that adds a few samples to the pixel's running
//! sum in a storage buffer, so progress can be reported between passes and no single dispatch
//! runs long enough to trip a driver watchdog. The sum is read back once at the end.
use crate::render::{Compiled, Progress, RenderSettings, Rendered};
use anyhow::{anyhow, bail, Context, Result};
use shared::glam::Vec4;
use shared::layout::RenderParams;
use wgpu::util::DeviceExt;

static KERNEL_SPV: &[u8] = include_bytes!(env!("kernel.spv"));
const ENTRY_POINT: &str = "render_pass";
/// The kernel's workgroup size (`threads(8, 8, 1)`).
const GROUP: u32 = 8;
/// Samples per pixel added in one dispatch are chosen so a pass traces about this many paths.
const PATHS_PER_PASS: u64 = 1 << 18;

pub struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    pub adapter: wgpu::AdapterInfo,
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

impl Gpu {
    /// Opens the first adapter whose name contains `name` (case-insensitive), or the first one.
    pub fn open(name: Option<&str>) -> Result<Self> {
        let all = pollster::block_on(instance().enumerate_adapters(wgpu::Backends::PRIMARY));
        let names: Vec<String> = all.iter().map(|a| a.get_info().name).collect();
        let adapter = match name {
            Some(n) => all.into_iter().find(|a| a.get_info().name.to_lowercase().contains(&n.to_lowercase())).ok_or_else(|| anyhow!("no GPU adapter matches {n:?}; found {names:?}"))?,
            None => all.into_iter().next().ok_or_else(|| {
                anyhow!("no GPU adapter found (Vulkan, Metal or DX12). On Linux without a GPU, install Mesa's lavapipe: apt-get install mesa-vulkan-drivers libvulkan1")
            })?,
        };
        let info = adapter.get_info();
        let limits = adapter.limits();
        if limits.max_storage_buffers_per_shader_stage < 8 {
            bail!("adapter {:?} allows {} storage buffers per stage; the kernel needs 8", info.name, limits.max_storage_buffers_per_shader_stage);
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
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("kernel"), source: wgpu::util::make_spirv(KERNEL_SPV) });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(ENTRY_POINT),
            layout: None,
            module: &module,
            entry_point: Some(ENTRY_POINT),
            compilation_options: Default::default(),
            cache: None,
        });
        if let Some(e) = pollster::block_on(scope.pop()) {
            bail!("adapter {:?} rejected the kernel: {e}", info.name);
        }
        Ok(Self { device, queue, pipeline, adapter: info })
    }

    fn storage(&self, label: &str, data: &[u8]) -> wgpu::Buffer {
        self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents: data, usage: wgpu::BufferUsages::STORAGE })
    }

    pub fn render(&self, c: &Compiled, s: &RenderSettings, progress: Progress) -> Result<Rendered> {
        s.check()?;
        let pixels = s.width as u64 * s.height as u64;
        let limit = self.device.limits().max_storage_buffer_binding_size as u64;
        for (what, bytes) in [("triangles", std::mem::size_of_val(&c.scene.triangles[..])), ("k-d nodes", std::mem::size_of_val(&c.tree.nodes[..])), ("leaf indices", std::mem::size_of_val(&c.tree.indices[..])), ("image", pixels as usize * 16)] {
            if bytes as u64 > limit {
                bail!("{what}: {bytes} bytes exceed this adapter's storage-buffer limit of {limit} bytes");
            }
        }
        let device = &self.device;
        let params_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("params"),
            size: std::mem::size_of::<RenderParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let nodes = self.storage("nodes", bytemuck::cast_slice(&c.tree.nodes));
        // Storage buffers may not be empty: a tree always has a node, the rest get a zero word.
        let indices = self.storage("indices", bytemuck::cast_slice(if c.tree.indices.is_empty() { &[0u32][..] } else { &c.tree.indices }));
        let triangles = self.storage("triangles", bytemuck::cast_slice(&c.scene.triangles));
        let info = self.storage("info", bytemuck::cast_slice(&c.scene.info));
        let materials = self.storage("materials", bytemuck::cast_slice(&c.scene.materials));
        let lights = self.storage("lights", bytemuck::cast_slice(&c.lights));
        let accum_bytes = pixels * std::mem::size_of::<Vec4>() as u64;
        let accum = device.create_buffer(&wgpu::BufferDescriptor { label: Some("accum"), size: accum_bytes, usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC, mapped_at_creation: false });
        let primary = device.create_buffer(&wgpu::BufferDescriptor { label: Some("primary"), size: pixels * 4, usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC, mapped_at_creation: false });
        let layout = self.pipeline.get_bind_group_layout(0);
        let buffers = [&params_buffer, &nodes, &indices, &triangles, &info, &materials, &lights, &accum, &primary];
        let entries: Vec<wgpu::BindGroupEntry> = buffers.iter().enumerate().map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() }).collect();
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some("scene"), layout: &layout, entries: &entries });

        let per_pass = ((PATHS_PER_PASS / pixels.max(1)) as u32).clamp(1, s.spp);
        let total = pixels * s.spp as u64;
        let mut start = 0;
        while start < s.spp {
            let count = per_pass.min(s.spp - start);
            let params = c.params(s, start, count)?;
            self.queue.write_buffer(&params_buffer, 0, bytemuck::bytes_of(&params));
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("pass") });
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("render"), timestamp_writes: None });
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &bind_group, &[]);
                pass.dispatch_workgroups(s.width.div_ceil(GROUP), s.height.div_ceil(GROUP), 1);
            }
            self.queue.submit(Some(encoder.finish()));
            device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| anyhow!("GPU pass failed: {e}"))?;
            start += count;
            progress(pixels * start as u64, total);
        }
        let sum: Vec<Vec4> = self.read_back(&accum, accum_bytes)?;
        let primary: Vec<u32> = self.read_back(&primary, pixels * 4)?;
        Ok(Rendered { width: s.width, height: s.height, spp: s.spp, sum, primary })
    }

    fn read_back<T: bytemuck::Pod>(&self, src: &wgpu::Buffer, size: u64) -> Result<Vec<T>> {
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor { label: Some("staging"), size, usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST, mapped_at_creation: false });
        let mut encoder = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("read back") });
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
