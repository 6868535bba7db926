//! The `kdtrace` command line: `render`, `merge`, `verify`, `tree`, `rays`, `export`, `compile`, `compare`,
//! `pixel`, `serve`, `adapters`. One file per command; each prints text or, with `--json`, one
//! line serialised from its report struct. Input errors exit with code 2, a failed check with 1.
/// `println!` that returns the error instead of panicking when standard output is gone (a closed
/// pipe: `kdtrace rays … --json | head -1`); `run` ends quietly on a closed pipe.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout().lock(), $($arg)*)
    }};
}

mod args;
mod compare;
mod compile;
mod export;
mod merge;
mod pixel;
mod rays;
mod render;
mod serve;
mod tree;
mod verify;

use crate::render::{Compiled, Rendered};
use crate::settings::{Adaptive, RenderSettings};
use crate::{kdbuild, Loaded};
use anyhow::{Context, Result};
pub use args::Device;
use args::ImageArgs;
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

#[derive(Parser)]
#[command(name = "kdtrace", version, about = "A path tracer whose CPU reference and GPU kernel run the same Rust code")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene (.obj, .toml or .kdc) to PNG (sRGB) or EXR (linear).
    Render(render::RenderArgs),
    /// Render on the CPU and the GPU with the same seed and report how well they agree.
    Verify(verify::VerifyArgs),
    /// Add partial renders (`render --samples A..B --partial OUT.kdp`) into one image, equal
    /// bit for bit to one render of all their samples.
    Merge(merge::MergeArgs),
    /// Write a scene (.obj or .toml) as a TOML scene file stating every render setting.
    Export(export::ExportArgs),
    /// Parse a scene, build its k-d tree and write both to one binary .kdc file.
    Compile(compile::CompileArgs),
    /// List the GPU adapters wgpu can use.
    Adapters,
    /// Build a scene's k-d tree and report its statistics (and check it with --validate).
    Tree(tree::TreeArgs),
    /// Ray-casting throughput for primary, ambient-occlusion and diffuse rays (Aila & Laine).
    Rays(rays::RaysArgs),
    /// Compare a linear image (EXR or PFM) against a reference: RMSE, relMSE, MAE, ꟻLIP, NaN/Inf.
    Compare(compare::CompareArgs),
    /// Replay one sample of one pixel on the CPU and print its path as JSON: every vertex, light
    /// and BSDF sample, and the k-d nodes each ray visited.
    Pixel(pixel::PixelArgs),
    /// Serve the web UI: progressive renders with camera controls and a remote debugger that
    /// replays a pixel's sample (websocket protocol in the README).
    Serve(serve::ServeArgs),
}

/// Parses the command line, runs the command and maps its outcome to the exit code.
pub fn run() -> ExitCode {
    let result = match Cli::parse().command {
        Command::Render(a) => render::run(a),
        Command::Verify(a) => verify::run(a),
        Command::Tree(a) => tree::run(a),
        Command::Rays(a) => rays::run(a),
        Command::Export(a) => export::run(a),
        Command::Merge(a) => merge::run(a),
        Command::Compile(a) => compile::run(a),
        Command::Compare(a) => compare::run(a),
        Command::Pixel(a) => pixel::run(a),
        Command::Serve(a) => serve::run(a),
        Command::Adapters => adapters(),
    };
    match result {
        Ok(code) => code,
        // The reader of standard output left (`| head`): nothing is lost that it wanted.
        Err(e) if closed_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

/// Whether `e` comes from writing to a pipe whose reader has gone.
fn closed_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| c.downcast_ref::<std::io::Error>().is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe))
}

fn adapters() -> Result<ExitCode> {
    for a in crate::render::gpu::adapters() {
        outln!("{} ({:?}, {:?}, driver {} {})", a.name, a.device_type, a.backend, a.driver, a.driver_info)?;
    }
    Ok(ExitCode::SUCCESS)
}

/// Prints one report as a JSON line.
fn print_json(report: &impl serde::Serialize) -> Result<()> {
    outln!("{}", serde_json::to_string(report)?)?;
    Ok(())
}

/// Flags over the scene's own settings over the defaults, and how to render; an error names the
/// scene.
fn settings(a: &ImageArgs, loaded: &mut Loaded, scene: &Path) -> Result<RenderSettings> {
    let (lo, hi) = loaded.compiled.world_bounds();
    let context = || format!("{} with the command line's settings", scene.display());
    // A glTF camera's aspect ratio holds when the command line gives one side only.
    let mut flags = a.scene.clone();
    if let Some(aspect) = loaded.aspect {
        let side = |x: f64| x.round().clamp(1.0, crate::settings::MAX_SIDE as f64) as u32;
        match (flags.width, flags.height) {
            (Some(w), None) => flags.height = Some(side(w as f64 / aspect)),
            (None, Some(h)) => flags.width = Some(side(h as f64 * aspect)),
            _ => {}
        }
    }
    if let Some(e) = &a.environment {
        // A file that exists, or a name that is not three numbers, is a map; the rest a colour.
        let path = Path::new(e);
        let colour = crate::settings::scene::parse_color(e);
        match colour {
            Ok(c) if !path.exists() => {
                flags.environment = Some(c);
                loaded.compiled.scene.environment_map = None;
            }
            Err(msg) if !path.exists() && e.split(',').count() == 3 => anyhow::bail!("--environment {e}: {msg}"),
            _ => {
                let map = crate::scene::EnvironmentMap::read(path, 1.0, [0.0; 3])
                    .with_context(|| format!("--environment {e}"))?;
                loaded.compiled.scene.environment_map = Some(map);
                flags.environment = Some([0.0; 3]);
            }
        }
        loaded.compiled.prepare_emitters();
    }
    let mut s = loaded.settings.overridden_by(&flags).resolve(lo, hi).with_context(context)?;
    // The camera placed against the scene (its distance in the local frame), before any work.
    loaded.compiled.check_camera(&s).with_context(context)?;
    s.traversal = a.traversal;
    s.dispatch = a.dispatch;
    s.aov = a.aov;
    s.specialize = a.specialize == args::Switch::On;
    s.light_pool = a.light_pool == args::Switch::On;
    s.adaptive = a.adaptive.map(|threshold| Adaptive { threshold, min_spp: a.min_spp, mode: a.adaptive_mode });
    s.check()?;
    if s.aov == crate::settings::Aov::Radiance && !crate::render::features::lit(&loaded.compiled, &s) {
        eprintln!(
            "warning: {}: {}; --environment R,G,B lights it from every direction",
            scene.display(),
            crate::render::features::UNLIT
        );
    }
    Ok(s)
}

/// Loads a scene, building its tree (unless stored) with `build`, and reports its warnings on
/// stderr.
pub(crate) fn load(path: &Path, build: kdbuild::BuildSettings, camera: Option<&str>) -> Result<Loaded> {
    warn(crate::render::load::load_with_camera(path, build, camera)?)
}

/// `load`, the k-d tree left to be built when first asked for (`render::load::load_deferred`).
pub(crate) fn load_deferred(path: &Path, build: kdbuild::BuildSettings, camera: Option<&str>) -> Result<Loaded> {
    warn(crate::render::load::load_deferred(path, build, camera)?)
}

fn warn(loaded: Loaded) -> Result<Loaded> {
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    Ok(loaded)
}

pub(crate) fn progress_bar(quiet: bool, label: &str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(1);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {percent}% {elapsed_precise} eta {eta}")
            .unwrap()
            .progress_chars("=> "),
    );
    bar.set_message(label.to_string());
    bar
}

/// A render on one device, with a progress bar unless `--json`.
struct DeviceRun {
    image: Rendered,
    /// The CPU's thread count or the adapter's name.
    adapter: String,
    render_s: f64,
    /// With several devices, what each rendered.
    shares: Option<Vec<crate::render::multi::Share>>,
}

fn run_device(device: Device, c: &Compiled, s: &RenderSettings, a: &ImageArgs) -> Result<DeviceRun> {
    crate::render::memory::check(s.width, s.height, device == Device::Gpu)?;
    let bar = progress_bar(a.json, device.name());
    let report = |done: u64, total: u64| {
        bar.set_length(total);
        bar.set_position(done);
    };
    let run = match device {
        Device::Cpu => {
            let t = Instant::now();
            let image = crate::render::cpu::render(c, s, &report)?;
            let adapter = crate::render::cpu::adapter_name(rayon::current_num_threads());
            DeviceRun { image, adapter, render_s: t.elapsed().as_secs_f64(), shares: None }
        }
        Device::Gpu => {
            let g = crate::render::gpu::Gpu::open(a.adapter.as_deref())?;
            g.prepare(c, s)?;
            let t = Instant::now();
            let image = g.render(c, s, &report)?;
            DeviceRun { image, adapter: g.adapter.name.clone(), render_s: t.elapsed().as_secs_f64(), shares: None }
        }
    };
    bar.finish_and_clear();
    Ok(run)
}
