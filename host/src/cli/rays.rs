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
    // K_I prices a leaf test of `leaf_block` triangles; the counts are of triangles.
    let per_triangle = build.intersection_cost as f64 / build.leaf_block.max(1) as f64;
    let mut primary_rate = None;
    for kind in [RayKind::Primary, RayKind::Ao, RayKind::Diffuse] {
        let batch = make_rays(c, &s, kind, traversal)?;
        let (t, _) = measure(c, g.as_ref(), kind, &batch, r.repeats)?;
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
