//! The `kdtrace` command line: `render`, `verify`, `tree`, `rays`, `export`, `compile`, `compare`, `adapters`.
use anyhow::Result;
use clap::{Args, Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use kdtrace::render::{Aov, Compiled, Dispatch, RenderSettings, Rendered, SamplerKind, Traversal};
use kdtrace::scene_settings::SceneSettings;
use kdtrace::{cpu, gpu, image_io, kdbuild, kdc, scene_file, verify, Loaded, SceneKind};
use serde_json::json;
use shared::glam::Vec3;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// The k-d build allocates event lists per node by the million; mimalloc serves that several
/// times faster than the system allocator.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

#[derive(Parser)]
#[command(name = "kdtrace", version, about = "A path tracer whose CPU reference and GPU kernel run the same Rust code")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene (.obj, .toml or .kdc) to PNG (sRGB) or EXR (linear).
    Render(RenderArgs),
    /// Render on the CPU and the GPU with the same seed and report how well they agree.
    Verify(VerifyArgs),
    /// Write a scene (.obj or .toml) as a TOML scene file stating every render setting.
    Export(ExportArgs),
    /// Parse a scene, build its k-d tree and write both to one binary .kdc file.
    Compile(CompileArgs),
    /// List the GPU adapters wgpu can use.
    Adapters,
    /// Build a scene's k-d tree and report its statistics (and check it with --validate).
    Tree(TreeArgs),
    /// Ray-casting throughput for primary, ambient-occlusion and diffuse rays (Aila & Laine).
    Rays(RaysArgs),
    /// Compare a linear image (EXR or PFM) against a reference: RMSE, relMSE, MAE, ꟻLIP, NaN/Inf.
    Compare(CompareArgs),
}

#[derive(Args)]
struct RaysArgs {
    scene: PathBuf,
    #[arg(long, value_enum, default_value_t = Device::Cpu)]
    device: Device,
    /// Timed runs after one warm-up; the fastest counts.
    #[arg(long, default_value_t = 3)]
    repeats: usize,
    #[command(flatten)]
    image: ImageArgs,
}

#[derive(Args)]
struct CompareArgs {
    /// Reference image (.exr or .pfm).
    reference: PathBuf,
    /// Test image (.exr or .pfm), same size.
    test: PathBuf,
    /// The test image's per-sample variance (`render --variance`): adds a per-pixel test of the
    /// test image against the reference (Šidák-corrected, α = 0.01). Needs --spp.
    #[arg(long, requires = "spp")]
    variance: Option<PathBuf>,
    /// Samples per pixel of the test image.
    #[arg(long)]
    spp: Option<u64>,
    /// Print one JSON line instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct TreeArgs {
    scene: PathBuf,
    #[command(flatten)]
    build: BuildArgs,
    /// Check every invariant of the tree (slow on big scenes).
    #[arg(long)]
    validate: bool,
    /// Print one JSON line instead of text.
    #[arg(long)]
    json: bool,
}

/// k-d tree build settings; defaults in `kdbuild::BuildSettings`.
#[derive(Args, Clone)]
struct BuildArgs {
    /// Tree builder.
    #[arg(long, value_enum)]
    builder: Option<kdbuild::Builder>,
    /// SAH cost of a traversal step (K_T).
    #[arg(long)]
    traversal_cost: Option<f32>,
    /// SAH cost of a triangle test (K_I).
    #[arg(long)]
    intersection_cost: Option<f32>,
    /// Triangles one leaf test covers in the SAH (1: every triangle counts).
    #[arg(long)]
    leaf_block: Option<u32>,
    /// SAH factor λ for splits with an empty side.
    #[arg(long)]
    empty_factor: Option<f32>,
    /// Maximum tree depth (0: 8 + 1.3·log2 N).
    #[arg(long)]
    max_depth: Option<u32>,
    /// Nodes with at most this many triangles become leaves.
    #[arg(long)]
    leaf_size: Option<u32>,
    /// Splits costlier than a leaf allowed on one path.
    #[arg(long)]
    bad_refines: Option<u32>,
    /// Most triangle references per triangle in the whole tree (0: no limit).
    #[arg(long)]
    max_refs_factor: Option<f32>,
}

impl BuildArgs {
    fn settings(&self) -> Result<kdbuild::BuildSettings> {
        let d = kdbuild::BuildSettings::default();
        let s = kdbuild::BuildSettings {
            builder: self.builder.unwrap_or(d.builder),
            traversal_cost: self.traversal_cost.unwrap_or(d.traversal_cost),
            intersection_cost: self.intersection_cost.unwrap_or(d.intersection_cost),
            leaf_block: self.leaf_block.unwrap_or(d.leaf_block),
            empty_factor: self.empty_factor.unwrap_or(d.empty_factor),
            max_depth: self.max_depth.unwrap_or(d.max_depth),
            leaf_size: self.leaf_size.unwrap_or(d.leaf_size),
            bad_refines: self.bad_refines.unwrap_or(d.bad_refines),
            max_refs_factor: self.max_refs_factor.unwrap_or(d.max_refs_factor),
        };
        s.check()?;
        Ok(s)
    }
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Device {
    Cpu,
    Gpu,
}

/// Image options. Each one given overrides the scene file; unset ones come from the scene file,
/// then from the built-in defaults (`kdtrace::scene_settings`).
#[derive(Args, Clone)]
struct ImageArgs {
    /// Samples per pixel [scene file, else 64; with a time limit, the most].
    #[arg(long)]
    spp: Option<u32>,
    /// Stop after SEC seconds, between passes of whole samples (every pixel gets the same
    /// number); the spp reached is reported [scene file, else none].
    #[arg(long, value_name = "SEC")]
    time_limit: Option<f64>,
    /// [scene file, else 512]
    #[arg(long)]
    width: Option<u32>,
    /// [scene file, else 512]
    #[arg(long)]
    height: Option<u32>,
    /// Indirect bounces, 0 = direct light only [scene file, else 6].
    #[arg(long)]
    bounces: Option<u32>,
    /// [scene file, else 0]
    #[arg(long)]
    seed: Option<u32>,
    /// Sample placement: shuffled Owen-scrambled Sobol points, or independent uniforms [scene
    /// file, else sobol].
    #[arg(long, value_enum)]
    sampler: Option<SamplerKind>,
    /// Camera position x,y,z (default: frame the scene's box from +Z).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    eye: Option<Vec3>,
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    target: Option<Vec3>,
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    up: Option<Vec3>,
    /// Vertical field of view in degrees.
    #[arg(long)]
    fov: Option<f32>,
    /// GPU adapter: the first whose name contains this (default: the first adapter).
    #[arg(long)]
    adapter: Option<String>,
    /// Print one JSON line to stdout instead of a progress bar.
    #[arg(long)]
    json: bool,
    /// k-d traversal: a short stack with restart, a stack as deep as the tree, or the faster one
    /// for the device (full on CPUs and lavapipe, short on GPUs).
    #[arg(long, value_enum, default_value_t)]
    traversal: Traversal,
    /// GPU work distribution: one invocation per pixel, or persistent threads.
    #[arg(long, value_enum, default_value_t)]
    dispatch: Dispatch,
    /// Image content: radiance, or the camera ray's traversal cost (PNG: heat map of nodes +
    /// triangle tests; EXR: nodes, tests, restarts per pixel).
    #[arg(long, value_enum, default_value_t)]
    aov: Aov,
}

#[derive(Args)]
struct RenderArgs {
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

#[derive(Args)]
struct VerifyArgs {
    scene: PathBuf,
    #[command(flatten)]
    image: ImageArgs,
}

fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!("expected x,y,z, got {s:?}"));
    }
    let mut v = [0.0f32; 3];
    for (slot, p) in v.iter_mut().zip(parts) {
        *slot = p.trim().parse().map_err(|_| format!("{p:?} is not a number"))?;
        if !slot.is_finite() {
            return Err(format!("{p:?} is not finite"));
        }
    }
    Ok(Vec3::from(v))
}

/// The flags as scene settings (unset flags stay unset).
fn flag_settings(a: &ImageArgs) -> SceneSettings {
    SceneSettings {
        width: a.width,
        height: a.height,
        spp: a.spp,
        bounces: a.bounces,
        seed: a.seed,
        sampler: a.sampler,
        time_limit_s: a.time_limit,
        eye: a.eye.map(|v| v.to_array()),
        target: a.target.map(|v| v.to_array()),
        up: a.up.map(|v| v.to_array()),
        fov_deg: a.fov,
        ..Default::default()
    }
}

/// Flags over the scene's own settings over the defaults.
fn settings(a: &ImageArgs, loaded: &Loaded) -> Result<RenderSettings> {
    let c = &loaded.compiled;
    let (lo, hi) = c.world_bounds();
    let mut s = loaded.settings.overridden_by(&flag_settings(a)).resolve(lo, hi)?;
    s.traversal = a.traversal;
    s.dispatch = a.dispatch;
    s.aov = a.aov;
    Ok(s)
}

/// The tree's build settings for the device that traverses it: the CPU tests leaves eight
/// triangles at a time, a GPU thread one by one (`kdbuild::BuildSettings::for_gpu`).
fn build_settings(device: Device) -> kdbuild::BuildSettings {
    match device {
        Device::Cpu => kdbuild::BuildSettings::default(),
        Device::Gpu => kdbuild::BuildSettings::for_gpu(),
    }
}

/// Loads a scene, building its tree (unless stored) with `build`, and reports its warnings on
/// stderr.
fn load(path: &std::path::Path, build: kdbuild::BuildSettings) -> Result<Loaded> {
    let loaded = kdtrace::load(path, build)?;
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    Ok(loaded)
}

fn progress_bar(quiet: bool, label: &str) -> ProgressBar {
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

fn run_device(device: Device, c: &Compiled, s: &RenderSettings, a: &ImageArgs) -> Result<(Rendered, String, f64)> {
    let bar = progress_bar(a.json, if device == Device::Cpu { "cpu" } else { "gpu" });
    let report = |done: u64, total: u64| {
        bar.set_length(total);
        bar.set_position(done);
    };
    let result = match device {
        Device::Cpu => {
            let t = Instant::now();
            let r = cpu::render(c, s, &report)?;
            (r, format!("cpu ({} threads)", rayon::current_num_threads()), t.elapsed().as_secs_f64())
        }
        Device::Gpu => {
            let g = gpu::Gpu::open(a.adapter.as_deref())?;
            g.prepare(s.dispatch)?;
            let t = Instant::now();
            let r = g.render(c, s, &report)?;
            (r, g.adapter.name.clone(), t.elapsed().as_secs_f64())
        }
    };
    bar.finish_and_clear();
    Ok(result)
}

fn render(r: RenderArgs) -> Result<ExitCode> {
    image_io::check_output_path(&r.out)?;
    if let Some(v) = &r.variance {
        if !image_io::is_exr(v) {
            anyhow::bail!("{}: the variance image is linear: write it as .exr", v.display());
        }
    }
    let loaded = load(&r.scene, build_settings(r.device))?;
    let c = &loaded.compiled;
    let s = settings(&r.image, &loaded)?;
    let (img, adapter, render_s) = run_device(r.device, c, &s, &r.image)?;
    let pixels = img.mean();
    if s.aov == Aov::Cost && !image_io::is_exr(&r.out) {
        image_io::write_image(&r.out, s.width, s.height, &image_io::heat_map(&pixels))?;
    } else {
        image_io::write_image(&r.out, s.width, s.height, &pixels)?;
    }
    if let Some(v) = &r.variance {
        image_io::write_image(v, s.width, s.height, &img.variance())?;
    }
    let samples = s.width as f64 * s.height as f64 * img.spp as f64;
    if r.image.json {
        let line = json!({
            "scene": r.scene, "out": r.out,
            "device": if r.device == Device::Cpu { "cpu" } else { "gpu" }, "adapter": adapter,
            "triangles": c.scene.triangles.len(), "lights": c.scene.lights.len(),
            "dropped_degenerate": c.scene.dropped_degenerate,
            "nodes": c.tree.nodes.len(), "tree_depth": c.tree.depth,
            "spp": img.spp, "spp_max": s.spp, "time_limit_s": s.time_limit_s, "variance": r.variance,
            "width": s.width, "height": s.height, "bounces": s.max_bounces, "seed": s.seed, "sampler": s.sampler,
            "load_s": loaded.load_s, "build_s": loaded.build_s, "prepare_s": loaded.prepare_s, "render_s": render_s,
            "samples_per_s": samples / render_s, "zeroed_samples": img.zeroed_samples(),
            "traversal": img.traversal, "dispatch": s.dispatch, "aov": s.aov,
        });
        let mut line = line;
        if s.aov == Aov::Cost {
            let n = pixels.len() as f64;
            let mean = |k: usize| pixels.iter().map(|p| p[k] as f64).sum::<f64>() / n;
            line["mean_nodes"] = json!(mean(0));
            line["mean_tests"] = json!(mean(1));
            line["mean_restarts"] = json!(mean(2));
        }
        println!("{line}");
    } else {
        eprintln!(
            "{}: {} triangles, {}x{} at {} spp on {adapter}: load {:.3} s, build {:.3} s, prepare {:.3} s, render {:.3} s ({:.2} Msamples/s)",
            r.out.display(), c.scene.triangles.len(), s.width, s.height, img.spp, loaded.load_s, loaded.build_s, loaded.prepare_s, render_s, samples / render_s / 1e6
        );
    }
    Ok(ExitCode::SUCCESS)
}

fn verify(v: VerifyArgs) -> Result<ExitCode> {
    // One tree for both devices (the CPU's), so any difference is the devices', not the trees'.
    let loaded = load(&v.scene, build_settings(Device::Cpu))?;
    let c = &loaded.compiled;
    let mut s = settings(&v.image, &loaded)?;
    if s.time_limit_s.take().is_some() {
        // Both devices must render the same samples to be compared: a budget would stop them
        // at different spp.
        if v.image.time_limit.is_some() {
            anyhow::bail!("verify renders the same samples on both devices: --time-limit does not apply (use --spp)");
        }
        if v.image.spp.is_none() && loaded.settings.spp.is_none() {
            s.spp = kdtrace::scene_settings::DEFAULT_SPP;
        }
    }
    let (cpu_img, cpu_name, cpu_s) = run_device(Device::Cpu, c, &s, &v.image)?;
    let (gpu_img, gpu_name, gpu_s) = run_device(Device::Gpu, c, &s, &v.image)?;
    let a = verify::compare(&cpu_img, &gpu_img);
    if v.image.json {
        println!(
            "{}",
            json!({ "scene": v.scene, "cpu": cpu_name, "adapter": gpu_name, "cpu_render_s": cpu_s, "gpu_render_s": gpu_s, "spp": s.spp, "width": s.width, "height": s.height, "agreement": a })
        );
    } else {
        println!(
            "scene {} ({}x{}, {} spp, seed {}): CPU {cpu_name} {cpu_s:.3} s, GPU {gpu_name} {gpu_s:.3} s",
            v.scene.display(),
            s.width,
            s.height,
            s.spp,
            s.seed
        );
        println!(
            "pixels within {:e} relative: {}/{} ({:.4}%), bit-identical {}; relMSE {:.3e}; max relative difference {:.3e}",
            verify::REL_TOLERANCE, a.pixels_within, a.pixels, 100.0 * a.pixel_share, a.bitwise_identical_pixels, a.relmse, a.max_rel_diff
        );
        println!("primary hits identical: {}/{} ({:.4}%)", a.primary_matches, a.pixels, 100.0 * a.primary_share);
        if let Some(d) = &a.first_divergent {
            println!("first divergent pixel ({}, {}): cpu {:?} gpu {:?}", d.x, d.y, d.cpu, d.gpu);
        }
        println!("{}", if a.pass { "AGREE" } else { "DISAGREE" });
    }
    Ok(if a.pass { ExitCode::SUCCESS } else { ExitCode::from(1) })
}

fn tree(t: TreeArgs) -> Result<ExitCode> {
    let settings = t.build.settings()?;
    let loaded = kdtrace::load(&t.scene, settings)?;
    let c = &loaded.compiled;
    let st = kdbuild::stats(&c.tree, c.scene.triangles.len(), &settings);
    let valid = if t.validate { Some(kdbuild::validate(&c.tree, &c.scene.triangles)) } else { None };
    if t.json {
        let mut line = serde_json::to_value(&st)?;
        let extra = json!({
            "scene": t.scene, "builder": settings.builder, "settings": settings, "threads": rayon::current_num_threads(),
            "load_s": loaded.load_s, "build_s": loaded.build_s, "prepare_s": loaded.prepare_s,
            "mtris_per_s": c.scene.triangles.len() as f64 / loaded.build_s / 1e6,
            "valid": valid.as_ref().map(|v| v.is_ok()), "invalid_reason": valid.as_ref().and_then(|v| v.as_ref().err()),
        });
        line.as_object_mut().unwrap().extend(extra.as_object().unwrap().clone());
        println!("{line}");
    } else {
        println!(
            "{}: {} triangles, {:?} tree: {} nodes, {} leaves ({} empty), depth {}, {} refs ({:.2} per non-empty leaf), SAH cost {:.2}; built in {:.3} s on {} threads ({:.2} Mtris/s)",
            t.scene.display(), st.triangles, settings.builder, st.nodes, st.leaves, st.empty_leaves, st.max_depth, st.total_refs, st.mean_leaf_refs, st.sah_cost,
            loaded.build_s, rayon::current_num_threads(), st.triangles as f64 / loaded.build_s / 1e6
        );
        if let Some(v) = &valid {
            println!(
                "{}",
                match v {
                    Ok(()) => "valid".to_string(),
                    Err(e) => format!("INVALID: {e}"),
                }
            );
        }
    }
    Ok(if valid.is_some_and(|v| v.is_err()) { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

fn rays(r: RaysArgs) -> Result<ExitCode> {
    use kdtrace::raybench::{ideal_mrays_per_s, make_rays, measure, RayKind};
    let build = build_settings(r.device);
    let loaded = load(&r.scene, build)?;
    let c = &loaded.compiled;
    let s = settings(&r.image, &loaded)?;
    let g = match r.device {
        Device::Gpu => Some(gpu::Gpu::open(r.image.adapter.as_deref())?),
        Device::Cpu => None,
    };
    let adapter = g
        .as_ref()
        .map_or_else(|| format!("cpu ({} threads)", rayon::current_num_threads()), |g| g.adapter.name.clone());
    let traversal = s.traversal.resolve(g.as_ref().is_none_or(|g| g.is_cpu()));
    let mut primary_rate = None;
    for kind in [RayKind::Primary, RayKind::Ao, RayKind::Diffuse] {
        let batch = make_rays(c, &s, kind, traversal)?;
        let (t, _) = measure(c, g.as_ref(), kind, &batch, r.repeats)?;
        let primary = primary_rate.get_or_insert_with(|| t.clone());
        // K_I prices a leaf test of `leaf_block` triangles; the counts are of triangles.
        let per_triangle = build.intersection_cost as f64 / build.leaf_block.max(1) as f64;
        let ideal = Some(ideal_mrays_per_s(
            primary,
            t.nodes_per_ray,
            t.tests_per_ray,
            build.traversal_cost as f64,
            per_triangle,
        ));
        if r.image.json {
            let mut line = serde_json::to_value(&t)?;
            let extra = json!({
                "scene": r.scene, "device": if r.device == Device::Cpu { "cpu" } else { "gpu" }, "adapter": adapter,
                "traversal": traversal, "triangles": c.scene.triangles.len(), "width": s.width, "height": s.height,
                "ideal_mrays_per_s": ideal, "measured_over_ideal": ideal.map(|i| t.mrays_per_s / i),
            });
            line.as_object_mut().unwrap().extend(extra.as_object().unwrap().clone());
            println!("{line}");
        } else {
            println!(
                "{:?}: {} rays ({} hits) in {:.4} s: {:.2} Mrays/s; per ray {:.1} nodes, {:.1} tests, {:.3} restarts; ideal {} ({adapter}, {:?} stack)",
                kind, t.rays, t.hits, t.seconds, t.mrays_per_s, t.nodes_per_ray, t.tests_per_ray, t.restarts_per_ray,
                ideal.map_or("n/a".into(), |i| format!("{i:.2} Mrays/s, measured/ideal {:.2}", t.mrays_per_s / i)), traversal
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}

#[derive(Args)]
struct ExportArgs {
    scene: PathBuf,
    /// The TOML scene file to write (mesh paths are written relative to it).
    #[arg(long)]
    out: PathBuf,
}

fn export(e: ExportArgs) -> Result<ExitCode> {
    if SceneKind::of(&e.out).ok() != Some(SceneKind::Toml) {
        anyhow::bail!("{}: export writes a .toml scene file", e.out.display());
    }
    let file = match SceneKind::of(&e.scene)? {
        SceneKind::Kdc => anyhow::bail!(
            "{}: a compiled scene keeps no mesh files and cannot be exported; export the scene it was compiled from",
            e.scene.display()
        ),
        SceneKind::Obj => scene_file::for_obj(&e.scene),
        SceneKind::Toml => {
            let text = std::fs::read_to_string(&e.scene)
                .map_err(|err| anyhow::anyhow!("{}: cannot read: {err}", e.scene.display()))?;
            scene_file::parse(&e.scene, &text)?
        }
    };
    // Loading checks every mesh and resolves the camera framing that the file may leave open.
    let loaded = load(&e.scene, kdbuild::BuildSettings::default())?;
    let c = &loaded.compiled;
    let (lo, hi) = c.world_bounds();
    let resolved = loaded.settings.resolve(lo, hi)?;
    let mut file = scene_file::with_settings(file, &SceneSettings::pinned(&resolved, loaded.settings.time_limit_s))?;
    scene_file::rebase_meshes(&mut file, &e.scene, &e.out)?;
    let comment = format!(
        "kdtrace scene file, written by `kdtrace export` from {}.\nSchema: README.md, \"Scene files\".",
        e.scene.display()
    );
    let text = scene_file::to_toml(&file, &comment)?;
    std::fs::write(&e.out, text).map_err(|err| anyhow::anyhow!("{}: cannot write: {err}", e.out.display()))?;
    eprintln!("{}: {} meshes, {} triangles", e.out.display(), file.meshes.len(), c.scene.triangles.len());
    Ok(ExitCode::SUCCESS)
}

#[derive(Args)]
struct CompileArgs {
    scene: PathBuf,
    /// The .kdc file to write.
    #[arg(long)]
    out: PathBuf,
    /// Print one JSON line to stdout.
    #[arg(long)]
    json: bool,
}

fn compile(a: CompileArgs) -> Result<ExitCode> {
    if SceneKind::of(&a.out).ok() != Some(SceneKind::Kdc) {
        anyhow::bail!("{}: compile writes a .kdc file", a.out.display());
    }
    let build = kdbuild::BuildSettings::default();
    let loaded = load(&a.scene, build)?;
    let t = Instant::now();
    kdc::write(&a.out, &loaded.compiled, &build, &loaded.settings)?;
    let write_s = t.elapsed().as_secs_f64();
    let c = &loaded.compiled;
    let bytes = std::fs::metadata(&a.out).map(|m| m.len()).unwrap_or(0);
    if a.json {
        println!(
            "{}",
            json!({ "scene": a.scene, "out": a.out, "triangles": c.scene.triangles.len(), "nodes": c.tree.nodes.len(), "bytes": bytes, "load_s": loaded.load_s, "build_s": loaded.build_s, "prepare_s": loaded.prepare_s, "write_s": write_s })
        );
    } else {
        eprintln!(
            "{}: {} triangles, {} nodes, {bytes} bytes (load {:.3} s, build {:.3} s, write {write_s:.3} s)",
            a.out.display(),
            c.scene.triangles.len(),
            c.tree.nodes.len(),
            loaded.load_s,
            loaded.build_s
        );
    }
    Ok(ExitCode::SUCCESS)
}

fn compare(a: CompareArgs) -> Result<ExitCode> {
    use kdtrace::metrics::{errors, pixel_test, LinearImage, PixelStats};
    let read = |p: &PathBuf| -> Result<LinearImage> {
        let (w, h, px) = image_io::read_linear_image(p)?;
        LinearImage::new(w, h, px)
    };
    let (r, t) = (read(&a.reference)?, read(&a.test)?);
    if (r.width, r.height) != (t.width, t.height) {
        anyhow::bail!(
            "{} is {}x{} but {} is {}x{}: images of different sizes",
            a.reference.display(),
            r.width,
            r.height,
            a.test.display(),
            t.width,
            t.height
        );
    }
    let e = errors(&r, &t)?;
    let test = match (&a.variance, a.spp) {
        (Some(v), Some(spp)) => {
            let variance = read(v)?;
            if (variance.width, variance.height) != (t.width, t.height) {
                anyhow::bail!(
                    "{} is {}x{} but {} is {}x{}: images of different sizes",
                    v.display(),
                    variance.width,
                    variance.height,
                    a.test.display(),
                    t.width,
                    t.height
                );
            }
            let count = vec![spp; t.pixels.len()];
            Some(pixel_test(&r, &PixelStats { mean: t.clone(), variance, count }, 0.01)?)
        }
        _ => None,
    };
    if a.json {
        let mut line = serde_json::to_value(&e)?;
        line.as_object_mut().unwrap().extend([
            ("reference".to_string(), json!(a.reference)),
            ("test".to_string(), json!(a.test)),
            ("pixel_test".to_string(), json!(test)),
        ]);
        println!("{line}");
    } else {
        if let Some(p) = &test {
            println!(
                "per-pixel test (Šidák, α = 0.01): {} of {} channel values rejected at {:.3e}, smallest p {:.3e}{}: {}",
                p.rejected,
                p.tests,
                p.per_test_alpha,
                p.min_p,
                p.worst.map_or(String::new(), |(x, y, k)| format!(" at ({x}, {y}) channel {k}")),
                if p.pass { "consistent" } else { "INCONSISTENT" }
            );
        }
        println!(
            "{} vs reference {} ({}x{}): RMSE {:.6e}, relMSE {:.6e}, MAE {:.6e}, FLIP {:.6} ({} ppd), mean ratio {:.6}; NaN/Inf: reference {}/{}, test {}/{}",
            a.test.display(), a.reference.display(), e.width, e.height, e.rmse, e.relmse, e.mae, e.flip, e.flip_ppd, e.mean_ratio,
            e.reference_nonfinite.nan, e.reference_nonfinite.inf, e.test_nonfinite.nan, e.test_nonfinite.inf
        );
    }
    Ok(if test.is_some_and(|p| !p.pass) { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(r) => render(r),
        Command::Verify(v) => verify(v),
        Command::Tree(t) => tree(t),
        Command::Rays(r) => rays(r),
        Command::Export(e) => export(e),
        Command::Compile(c) => compile(c),
        Command::Compare(a) => compare(a),
        Command::Adapters => {
            for a in gpu::adapters() {
                println!("{} ({:?}, {:?}, driver {} {})", a.name, a.device_type, a.backend, a.driver, a.driver_info);
            }
            Ok(ExitCode::SUCCESS)
        }
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
