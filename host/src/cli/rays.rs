//! `kdtrace rays`: ray-casting throughput for Aila & Laine's three ray kinds.
use super::args::{Device, ImageArgs};
use super::{load, print_json, settings};
use crate::render::gpu::Gpu;
use crate::render::raybench::{ideal_mrays_per_s, make_rays, measure, RayKind, Throughput};
use crate::settings::Traversal;
use anyhow::{bail, Result};
use clap::Args;
use serde::Serialize;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args)]
pub struct RaysArgs {
    scene: PathBuf,
    #[arg(long, value_enum, default_value_t = Device::Cpu)]
    device: Device,
    /// Timed runs after one warm-up; the fastest counts.
    #[arg(long, default_value_t = 3)]
    repeats: usize,
    /// CPU, wide BVH: cast runs of 16 consecutive rays (neighbouring pixels) as one packet
    /// (`shared::wide_packet`), each node loaded once for the packet's rays that reach it
    #[arg(long)]
    packets: bool,
    /// Order each kind's rays by direction octant, then by the Morton code of their origins (as
    /// a wavefront integrator could sort its rays) before casting them
    #[arg(long)]
    sort: bool,
    /// Camera rays a pixel, one after another, through jittered points (with --packets and 16,
    /// a packet holds one pixel's samples and the rays from their hits, as Mitsuba's wavefront
    /// keeps a pixel's samples in adjacent lanes)
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pixel_samples: u32,
    #[command(flatten)]
    image: ImageArgs,
}

/// `rays --json`: one line per ray kind.
#[derive(Serialize)]
struct RaysReport<'a> {
    #[serde(flatten)]
    throughput: &'a Throughput,
    scene: &'a PathBuf,
    device: Device,
    adapter: &'a str,
    traversal: Traversal,
    packets: bool,
    sorted: bool,
    pixel_samples: u32,
    triangles: usize,
    width: u32,
    height: u32,
    /// The primary rays' rate scaled by this kind's SAH work per ray.
    ideal_mrays_per_s: f64,
    measured_over_ideal: f64,
}

pub fn run(r: RaysArgs) -> Result<ExitCode> {
    if r.repeats == 0 {
        bail!("--repeats must be at least 1");
    }
    let build = r.device.build_settings();
    let mut loaded = load(&r.scene, build, r.image.camera.as_deref())?;
    let s = settings(&r.image, &mut loaded, &r.scene)?;
    let c = &loaded.compiled;
    let g = match r.device {
        Device::Gpu => Some(Gpu::open(r.image.adapter.as_deref())?),
        Device::Cpu => None,
    };
    let adapter = g
        .as_ref()
        .map_or_else(|| crate::render::cpu::adapter_name(rayon::current_num_threads()), |g| g.adapter.name.clone());
    let traversal = match &g {
        Some(g) => s.traversal.for_adapter(g.is_cpu())?,
        None => s.traversal.for_cpu_path(),
    };
    if r.packets && (g.is_some() || traversal != Traversal::Wide) {
        bail!("--packets casts through the CPU path's wide BVH: use it with --device cpu and the wide traversal");
    }
    // K_I prices a leaf test of `leaf_block` triangles; the counts are of triangles.
    let per_triangle = build.intersection_cost as f64 / build.leaf_block.max(1) as f64;
    let mut primary_rate = None;
    for kind in [RayKind::Primary, RayKind::Ao, RayKind::Diffuse] {
        let mut batch = make_rays(c, &s, kind, traversal, r.pixel_samples)?;
        if r.sort {
            sort_rays(&mut batch, c.bounds_min, c.bounds_max);
        }
        let (t, _) = measure(c, g.as_ref(), kind, &batch, r.repeats, r.packets)?;
        let primary = primary_rate.get_or_insert_with(|| t.clone());
        let ideal =
            ideal_mrays_per_s(primary, t.nodes_per_ray, t.tests_per_ray, build.traversal_cost as f64, per_triangle);
        if r.image.json {
            print_json(&RaysReport {
                throughput: &t,
                scene: &r.scene,
                device: r.device,
                adapter: &adapter,
                traversal,
                packets: r.packets,
                sorted: r.sort,
                pixel_samples: r.pixel_samples,
                triangles: c.scene.triangles.len(),
                width: s.width,
                height: s.height,
                ideal_mrays_per_s: ideal,
                measured_over_ideal: t.mrays_per_s / ideal,
            })?;
        } else {
            outln!(
                "{:?}: {} rays ({} hits) in {:.4} s: {:.2} Mrays/s; per ray {:.1} nodes, {:.1} tests, {:.3} \
                 restarts; ideal {ideal:.2} Mrays/s, measured/ideal {:.2} ({adapter}, {traversal:?})",
                kind,
                t.rays,
                t.hits,
                t.seconds,
                t.mrays_per_s,
                t.nodes_per_ray,
                t.tests_per_ray,
                t.restarts_per_ray,
                t.mrays_per_s / ideal,
            )?;
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Orders `rays` by direction octant, then by the Morton code (21 bits an axis, within the
/// scene box `lo`..`hi`) of their origins.
fn sort_rays(rays: &mut [shared::layout::RayQuery], lo: shared::glam::Vec3, hi: shared::glam::Vec3) {
    fn spread(mut x: u64) -> u64 {
        x &= 0x1fffff;
        x = (x | x << 32) & 0x1f00000000ffff;
        x = (x | x << 16) & 0x1f0000ff0000ff;
        x = (x | x << 8) & 0x100f00f00f00f00f;
        x = (x | x << 4) & 0x10c30c30c30c30c3;
        (x | x << 2) & 0x1249249249249249
    }
    let key = |q: &shared::layout::RayQuery| {
        let p = (shared::glam::Vec3::new(q.origin.x, q.origin.y, q.origin.z) - lo)
            / (hi - lo).max(shared::glam::Vec3::splat(1e-30));
        let c = |x: f32| (x.clamp(0.0, 1.0) * 1048575.0) as u64;
        let oct = ((q.dir.x < 0.0) as u64) | ((q.dir.y < 0.0) as u64) << 1 | ((q.dir.z < 0.0) as u64) << 2;
        (oct << 61) | (spread(c(p.x)) | spread(c(p.y)) << 1 | spread(c(p.z)) << 2) >> 3
    };
    rays.sort_by_key(key);
}
