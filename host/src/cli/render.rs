//! `kdtrace render`: one image on one device.
use super::args::{Device, ImageArgs};
use super::{load, print_json, run_device, settings};
use crate::files;
use crate::image::io;
use crate::render::features::{self, Features};
use crate::settings::{Adaptive, Aov, Dispatch, SamplerKind, Traversal};
use anyhow::{bail, Result};
use clap::Args;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Args)]
pub struct RenderArgs {
    scene: PathBuf,
    #[arg(long)]
    out: PathBuf,
    #[arg(long, value_enum, default_value_t = Device::Cpu)]
    device: Device,
    /// Also write each pixel's per-sample variance (linear EXR), for `compare --variance`.
    #[arg(long, value_name = "FILE.exr")]
    variance: Option<PathBuf>,
    #[command(flatten)]
    image: ImageArgs,
}

/// `render --json`.
#[derive(Serialize)]
struct RenderReport<'a> {
    scene: &'a PathBuf,
    out: &'a PathBuf,
    device: Device,
    adapter: &'a str,
    triangles: usize,
    lights: usize,
    dropped_degenerate: usize,
    nodes: usize,
    tree_depth: u32,
    /// Samples per pixel rendered (with adaptive sampling, the most any pixel holds).
    spp: u32,
    /// The fewest and the mean samples per pixel (equal to `spp` without adaptive sampling).
    spp_min: u32,
    spp_mean: f64,
    /// Adaptive sampling's threshold, pilot samples and mode.
    adaptive: Option<Adaptive>,
    /// The most it would have rendered (the spp asked for, or 2^20 under a time limit alone).
    spp_max: u32,
    time_limit_s: Option<f64>,
    variance: &'a Option<PathBuf>,
    width: u32,
    height: u32,
    bounces: u32,
    seed: u32,
    sampler: SamplerKind,
    load_s: f64,
    build_s: f64,
    prepare_s: f64,
    render_s: f64,
    samples_per_s: f64,
    zeroed_samples: u64,
    traversal: Traversal,
    dispatch: Dispatch,
    aov: Aov,
    /// What the scene uses and which integrator variant rendered it.
    features: Features,
    /// With `--aov cost`: the camera rays' mean nodes, triangle tests and restarts.
    #[serde(skip_serializing_if = "Option::is_none")]
    mean_nodes: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    mean_tests: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    mean_restarts: Option<f64>,
}

pub fn run(r: RenderArgs) -> Result<ExitCode> {
    io::check_output_path(&r.out)?;
    if let Some(v) = &r.variance {
        if !io::is_exr(v) {
            bail!("{}: the variance image is linear: write it as .exr", v.display());
        }
    }
    // Every output is checked before the scene is even read: a render is never lost to a
    // missing folder or a clash found at the end.
    let outputs: Vec<&Path> = std::iter::once(r.out.as_path()).chain(r.variance.as_deref()).collect();
    files::check_outputs(&outputs, &[&r.scene])?;
    let mut loaded = load(&r.scene, r.device.build_settings(), r.image.camera.as_deref())?;
    let s = settings(&r.image, &mut loaded, &r.scene)?;
    let c = &loaded.compiled;
    let run = run_device(r.device, c, &s, &r.image)?;
    let img = &run.image;
    let pixels = img.mean();
    if io::is_exr(&r.out) {
        io::write_image(&r.out, s.width, s.height, &pixels)?;
    } else {
        io::write_image(&r.out, s.width, s.height, &io::for_display(s.aov, &pixels))?;
    }
    if let Some(v) = &r.variance {
        io::write_image(v, s.width, s.height, &img.variance())?;
    }
    let spp_range = img.spp_range();
    let samples = s.width as f64 * s.height as f64 * spp_range.1;
    if r.image.json {
        let cost_mean = |k: usize| {
            (s.aov == Aov::Cost).then(|| pixels.iter().map(|p| p[k] as f64).sum::<f64>() / pixels.len() as f64)
        };
        print_json(&RenderReport {
            scene: &r.scene,
            out: &r.out,
            device: r.device,
            adapter: &run.adapter,
            triangles: c.scene.triangles.len(),
            lights: c.scene.lights.len(),
            dropped_degenerate: c.scene.dropped_degenerate,
            nodes: c.tree.nodes.len(),
            tree_depth: c.tree.depth,
            spp: spp_range.2,
            spp_min: spp_range.0,
            spp_mean: spp_range.1,
            adaptive: s.adaptive,
            spp_max: s.spp,
            time_limit_s: s.time_limit_s,
            variance: &r.variance,
            width: s.width,
            height: s.height,
            bounces: s.max_bounces,
            seed: s.seed,
            sampler: s.sampler,
            load_s: loaded.load_s,
            build_s: loaded.build_s,
            prepare_s: loaded.prepare_s,
            render_s: run.render_s,
            samples_per_s: samples / run.render_s,
            zeroed_samples: img.zeroed_samples(),
            traversal: img.traversal,
            dispatch: s.dispatch,
            aov: s.aov,
            features: {
                let mut f = features::analyse(c, &s);
                // The CPU compiles one variant per set of the non-material bits and material mode.
                if r.device == Device::Cpu && s.specialize {
                    f.variant_bits = crate::render::cpu::cpu_variant_bits(f.bits);
                }
                f
            },
            mean_nodes: cost_mean(0),
            mean_tests: cost_mean(1),
            mean_restarts: cost_mean(2),
        })?;
    } else {
        eprintln!(
            "{}: {} triangles, {}x{} at {} spp on {}: load {:.3} s, build {:.3} s, prepare {:.3} s, render {:.3} s \
             ({:.2} Msamples/s)",
            r.out.display(),
            c.scene.triangles.len(),
            s.width,
            s.height,
            img.spp,
            run.adapter,
            loaded.load_s,
            loaded.build_s,
            loaded.prepare_s,
            run.render_s,
            samples / run.render_s / 1e6
        );
    }
    Ok(ExitCode::SUCCESS)
}
