//! `kdtrace render`: one image, or a partial render for `merge` (`--samples A..B --partial`), on
//! one device or several at once (`--device all`, `render::multi`).
use super::args::{Device, ImageArgs};
use super::{load_deferred, print_json, run_device, settings, DeviceRun};
use crate::files;
use crate::image::io;
use crate::kdbuild::BuildSettings;
use crate::render::blocks::{Fold, Node};
use crate::render::features::{self, Features};
use crate::render::multi::{self, Share, Unit};
use crate::render::partial::{self, Header, ImageSettings, Partial};
use crate::render::progressive::Progressive;
use crate::render::{Compiled, Rendered};
use crate::settings::RenderSettings;
use crate::settings::{Adaptive, Aov, Connect, Dispatch, SamplerKind, Traversal};
use anyhow::{anyhow, bail, Result};
use clap::Args;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

#[derive(Args)]
pub struct RenderArgs {
    scene: PathBuf,
    /// The image: PNG (sRGB) or EXR (linear).
    #[arg(long, required_unless_present = "partial")]
    out: Option<PathBuf>,
    /// cpu, gpu (the adapter `--adapter` names, else the first), all (the CPU and every adapter
    /// at once), or a list such as cpu,gpu:0,gpu:1 (N from `kdtrace adapters`). Several devices
    /// share blocks of samples by their speed; the image is a single device's bit for bit where
    /// the devices compute alike (the CPU and lavapipe do).
    #[arg(long, default_value = "cpu", value_name = "cpu|gpu|all|LIST")]
    device: String,
    /// Also write each pixel's per-sample variance (linear EXR), for `compare --variance`.
    #[arg(long, value_name = "FILE.exr", conflicts_with = "partial")]
    variance: Option<PathBuf>,
    /// With --partial: render samples A (inclusive) to B (exclusive) of every pixel, A a multiple
    /// of 8 (B too, unless the part is the render's last); `--spp` is then not used [0..spp].
    #[arg(long, value_name = "A..B", value_parser = parse_samples, requires = "partial")]
    samples: Option<[u32; 2]>,
    /// Write a partial render (the samples' sums, the scene's hash and the image's settings) for
    /// `kdtrace merge` instead of an image.
    #[arg(long, value_name = "OUT.kdp", conflicts_with = "out")]
    partial: Option<PathBuf>,
    #[command(flatten)]
    image: ImageArgs,
}

/// `--samples A..B`.
fn parse_samples(v: &str) -> Result<[u32; 2], String> {
    let (a, b) = v.split_once("..").ok_or_else(|| format!("{v:?} is not a range A..B"))?;
    let n = |x: &str| x.trim().parse::<u32>().map_err(|_| format!("{x:?} in {v:?} is not a sample number"));
    Ok([n(a)?, n(b)?])
}

/// `--device`: one device, or several at once.
enum Devices {
    One(Device),
    Many(Vec<Unit>),
}

impl Devices {
    fn parse(spec: &str) -> Result<Self> {
        Ok(match spec {
            "cpu" => Devices::One(Device::Cpu),
            "gpu" => Devices::One(Device::Gpu),
            _ => Devices::Many(Unit::parse_list(spec)?),
        })
    }

    /// The k-d tree's build settings: the device's own for one device, the CPU's for several
    /// (every device then traverses the same tree: the CPU's image bit for bit on lavapipe).
    fn build_settings(&self, partial: bool) -> BuildSettings {
        match self {
            // Parts from any device merge: they all build the CPU's tree.
            Devices::One(_) if partial => BuildSettings::default(),
            Devices::One(d) => d.build_settings(),
            Devices::Many(_) => BuildSettings::default(),
        }
    }

    fn any_cpu(&self) -> bool {
        match self {
            Devices::One(d) => *d == Device::Cpu,
            Devices::Many(units) => units.contains(&Unit::Cpu),
        }
    }

    fn any_gpu(&self) -> bool {
        match self {
            Devices::One(d) => *d == Device::Gpu,
            Devices::Many(units) => units.iter().any(|u| *u != Unit::Cpu),
        }
    }
}

/// `render --json`.
#[derive(Serialize)]
struct RenderReport<'a> {
    scene: &'a PathBuf,
    out: &'a PathBuf,
    /// `--device` as given (cpu, gpu, all or a list).
    device: &'a str,
    /// With several devices, what each rendered.
    #[serde(skip_serializing_if = "Option::is_none")]
    devices: &'a Option<Vec<Share>>,
    adapter: &'a str,
    triangles: usize,
    lights: usize,
    dropped_degenerate: usize,
    /// The k-d tree's nodes and depth, where it was built (a GPU or a `--traversal full` or
    /// `short` render; a CPU render on the wide BVH builds none).
    #[serde(skip_serializing_if = "Option::is_none")]
    nodes: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    tree_depth: Option<u32>,
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
    connect: Connect,
    load_s: f64,
    build_s: f64,
    prepare_s: f64,
    render_s: f64,
    samples_per_s: f64,
    zeroed_samples: u64,
    traversal: Traversal,
    /// The CPU path's wide BVH, where it was built.
    #[serde(skip_serializing_if = "Option::is_none")]
    wide_bvh: Option<WideBvhReport>,
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

/// `render --json` `wide_bvh`: the CPU path's BVH (`crate::bvh`).
#[derive(Serialize)]
struct WideBvhReport {
    /// Eight-wide nodes.
    nodes: usize,
    /// Leaves, one eight-lane triangle block each.
    leaves: usize,
    /// Triangle references in the leaves: the triangles and the copies spatial splits made.
    references: usize,
    /// Levels of nodes on the longest path.
    depth: usize,
    /// The large triangles the CPU lanes test sixteen rays at a time, outside this tree's copy
    /// over the rest (`bvh::split`); 0 where the scene is not split.
    split_large: usize,
}

pub fn run(r: RenderArgs) -> Result<ExitCode> {
    let devices = Devices::parse(&r.device)?;
    if let Some(out) = &r.out {
        io::check_output_path(out)?;
    }
    if let Some(v) = &r.variance {
        if !io::is_exr(v) {
            bail!("{}: the variance image is linear: write it as .exr", v.display());
        }
    }
    if let Some([a, b]) = r.samples {
        partial::check_range(a, b)?;
    }
    // Every output is checked before the scene is even read: a render is never lost to a
    // missing folder or a clash found at the end.
    let outputs: Vec<&Path> = r.out.iter().chain(&r.partial).chain(&r.variance).map(PathBuf::as_path).collect();
    files::check_outputs(&outputs, &[&r.scene])?;
    if devices.any_gpu() {
        // Before the scene is read: a GPU has no wide BVH.
        r.image.traversal.check_for_adapter()?;
    }
    let mut loaded = load_deferred(&r.scene, devices.build_settings(r.partial.is_some()), r.image.camera.as_deref())?;
    let mut s = settings(&r.image, &mut loaded, &r.scene)?;
    let several = matches!(devices, Devices::Many(_));
    if r.partial.is_some() || several {
        let what = if several { "--device with several devices" } else { "--partial" };
        if s.adaptive.is_some() {
            bail!("{what} renders the same samples in every pixel: --adaptive does not apply");
        }
        if r.image.scene.time_limit_s.is_some() {
            bail!("{what} renders exactly the samples asked for: --time-limit does not apply");
        }
        if s.time_limit_s.take().is_some() {
            eprintln!("warning: {what} renders exactly the samples asked for: the scene file's time limit is ignored");
        }
    }
    if let Some([_, b]) = r.samples {
        s.spp = b;
        s.check()?;
    }
    crate::render::memory::check(s.width, s.height, devices.any_gpu())?;
    // The trees are built here rather than by the first pass, so that their time is reported
    // as building: the k-d tree for a GPU and for the CPU's k-d traversals, the wide BVH for
    // the CPU path on it.
    let cpu_wide = devices.any_cpu() && s.traversal.for_cpu_path() == crate::settings::Traversal::Wide;
    let t = std::time::Instant::now();
    if devices.any_gpu() || (devices.any_cpu() && !cpu_wide) || r.partial.is_some() {
        loaded.compiled.tree();
    }
    if cpu_wide && crate::render::cpu::runs_lanes(&s) {
        loaded.compiled.wide_bvh_and_split();
    } else if cpu_wide {
        loaded.compiled.wide_bvh();
    }
    loaded.build_s += t.elapsed().as_secs_f64();
    let c = &loaded.compiled;
    let range = r.samples.unwrap_or([0, s.spp]);
    let run = match (&devices, &r.partial) {
        (Devices::One(d), None) => run_device(*d, c, &s, &r.image)?,
        (_, partial) => {
            let (nodes, primary, adapter, shares, render_s) = match &devices {
                Devices::One(d) => {
                    let (nodes, adapter, render_s) = render_part(*d, c, &s, &r.image, range)?;
                    (nodes, None, adapter, None, render_s)
                }
                Devices::Many(units) => {
                    let bar = super::progress_bar(r.image.json, "devices");
                    let total = (range[1] - range[0]) as u64;
                    let shown = |shares: &[Share]| {
                        bar.set_length(total);
                        bar.set_position(shares.iter().map(|s| s.samples as u64).sum());
                        let parts: Vec<String> =
                            shares.iter().map(|s| format!("{} {:.0}%", s.device, 100.0 * s.share)).collect();
                        bar.set_message(parts.join(" · "));
                    };
                    let out = multi::render(c, &s, units, r.image.adapter.as_deref(), range, &shown)?;
                    bar.finish_and_clear();
                    let adapter = out.shares.iter().map(|s| s.device.as_str()).collect::<Vec<_>>().join(" + ");
                    (out.fold.into_nodes(), out.primary, adapter, Some(out.shares), out.render_s)
                }
            };
            if let Some(path) = partial {
                let part = Partial {
                    header: Header {
                        scene: r.scene.display().to_string(),
                        scene_hash: partial::scene_hash(c),
                        settings: ImageSettings::of(&s),
                        samples: range,
                        device: adapter.clone(),
                        nodes: nodes.iter().map(|n| n.id).collect(),
                    },
                    nodes,
                };
                part.write(path)?;
                return report_partial(&r, path, range, &adapter, render_s, shares, &s);
            }
            let mut fold = Fold::new(s.width as usize * s.height as usize);
            for n in nodes {
                fold.insert(n)?;
            }
            let (sums, spp) = fold.total(None)?.ok_or_else(|| anyhow!("no sample was rendered"))?;
            let image = Rendered {
                width: s.width,
                height: s.height,
                spp,
                sum: sums.sum,
                sum_sq: sums.sum_sq,
                primary: primary.unwrap_or_else(|| vec![shared::layout::NO_HIT; fold.pixels()]),
                traversal: s.traversal,
                counts: None,
            };
            DeviceRun { image, adapter, render_s, shares }
        }
    };
    let out = r.out.as_ref().ok_or_else(|| anyhow!("--out is missing"))?;
    let img = &run.image;
    let pixels = img.mean();
    if io::is_exr(out) {
        io::write_image(out, s.width, s.height, &pixels)?;
    } else {
        io::write_image(out, s.width, s.height, &io::for_display(s.aov, &pixels))?;
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
            out,
            device: &r.device,
            devices: &run.shares,
            adapter: &run.adapter,
            triangles: c.scene.triangles.len(),
            lights: c.scene.lights.len(),
            dropped_degenerate: c.scene.dropped_degenerate,
            nodes: c.has_tree().then(|| c.tree().nodes.len()),
            tree_depth: c.has_tree().then(|| c.tree().depth),
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
            connect: s.connect,
            load_s: loaded.load_s,
            build_s: loaded.build_s,
            prepare_s: loaded.prepare_s,
            render_s: run.render_s,
            samples_per_s: samples / run.render_s,
            zeroed_samples: img.zeroed_samples(),
            traversal: img.traversal,
            wide_bvh: c.wide.get().map(|b| WideBvhReport {
                nodes: b.nodes.len(),
                leaves: b.blocks.len(),
                references: b.references,
                depth: b.depth(),
                split_large: c.split.get().and_then(|s| s.as_ref()).map_or(0, |s| s.large_ids.len()),
            }),
            dispatch: s.dispatch,
            aov: s.aov,
            features: {
                let mut f = features::analyse(c, &s);
                // The CPU compiles one variant per set of the non-material bits and material mode.
                if matches!(devices, Devices::One(Device::Cpu)) && s.specialize {
                    f.variant_bits = crate::render::cpu::cpu_variant_bits(f.bits);
                }
                f.lanes = matches!(devices, Devices::One(Device::Cpu)) && crate::render::cpu::runs_lanes(&s);
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
            out.display(),
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

/// Renders samples `range` on one device, a block per pass with a progress bar: the fold's
/// nodes, the device's name and the seconds it rendered (after opening it and compiling).
fn render_part(
    device: Device,
    c: &Compiled,
    s: &RenderSettings,
    a: &ImageArgs,
    range: [u32; 2],
) -> Result<(Vec<Node>, String, f64)> {
    let gpu = match device {
        Device::Cpu => None,
        Device::Gpu => Some(crate::render::gpu::Gpu::open(a.adapter.as_deref())?),
    };
    let mut p: Box<dyn Progressive + '_> = match &gpu {
        None => Box::new(crate::render::cpu::progressive(c, s)?),
        Some(g) => Box::new(g.progressive(c, s)?),
    };
    let t = Instant::now();
    let bar = super::progress_bar(a.json, device.name());
    bar.set_length((range[1] - range[0]) as u64);
    p.start_at(range[0])?;
    let mut at = range[0];
    while at < range[1] {
        let n = (range[1] - at).min(crate::render::blocks::BLOCK_SAMPLES);
        p.pass(at, n)?;
        at += n;
        bar.set_position((at - range[0]) as u64);
    }
    bar.finish_and_clear();
    let render_s = t.elapsed().as_secs_f64();
    Ok((p.nodes()?, p.device(), render_s))
}

/// `render --partial --json`.
#[derive(Serialize)]
struct PartialReport<'a> {
    scene: &'a PathBuf,
    partial: &'a PathBuf,
    device: &'a str,
    adapter: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    devices: Option<Vec<Share>>,
    samples: [u32; 2],
    width: u32,
    height: u32,
    render_s: f64,
    samples_per_s: f64,
}

fn report_partial(
    r: &RenderArgs,
    path: &PathBuf,
    range: [u32; 2],
    adapter: &str,
    render_s: f64,
    shares: Option<Vec<Share>>,
    s: &RenderSettings,
) -> Result<ExitCode> {
    let samples = s.width as f64 * s.height as f64 * (range[1] - range[0]) as f64;
    if r.image.json {
        print_json(&PartialReport {
            scene: &r.scene,
            partial: path,
            device: &r.device,
            adapter,
            devices: shares,
            samples: range,
            width: s.width,
            height: s.height,
            render_s,
            samples_per_s: samples / render_s.max(1e-9),
        })?;
    } else {
        eprintln!(
            "{}: samples {}..{} of {}x{} on {adapter}: render {render_s:.3} s ({:.2} Msamples/s)",
            path.display(),
            range[0],
            range[1],
            s.width,
            s.height,
            samples / render_s.max(1e-9) / 1e6
        );
    }
    Ok(ExitCode::SUCCESS)
}
