//! `kdtrace compile`: parse a scene, build its k-d tree, write both to one `.kdc` file.
use super::args::BuildArgs;
use super::{load, print_json};
use crate::files;
use crate::render::kdc;
use crate::SceneKind;
use anyhow::{bail, Result};
use clap::Args;
use serde::Serialize;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

#[derive(Args)]
pub struct CompileArgs {
    scene: PathBuf,
    /// The .kdc file to write.
    #[arg(long)]
    out: PathBuf,
    /// Print one JSON line to stdout.
    #[arg(long)]
    json: bool,
    /// glTF scenes: the camera stored with the scene, by index or name (default: the first).
    #[arg(long, value_name = "NAME|INDEX")]
    camera: Option<String>,
    /// The tree's build settings (defaults: the CPU's tree, `kdbuild::BuildSettings`).
    #[command(flatten)]
    build: BuildArgs,
}

/// `compile --json`.
#[derive(Serialize)]
struct CompileReport<'a> {
    scene: &'a PathBuf,
    out: &'a PathBuf,
    triangles: usize,
    nodes: usize,
    bytes: u64,
    load_s: f64,
    build_s: f64,
    prepare_s: f64,
    write_s: f64,
}

pub fn run(a: CompileArgs) -> Result<ExitCode> {
    if SceneKind::of(&a.out).ok() != Some(SceneKind::Kdc) {
        bail!("{}: compile writes a .kdc file", a.out.display());
    }
    files::check_outputs(&[&a.out], &[&a.scene])?;
    let build = a.build.settings()?;
    let loaded = load(&a.scene, build, a.camera.as_deref())?;
    let t = Instant::now();
    kdc::write(&a.out, &loaded.compiled, &build, &loaded.settings)?;
    let write_s = t.elapsed().as_secs_f64();
    let c = &loaded.compiled;
    let bytes = std::fs::metadata(&a.out).map(|m| m.len()).unwrap_or(0);
    if a.json {
        print_json(&CompileReport {
            scene: &a.scene,
            out: &a.out,
            triangles: c.scene.triangles.len(),
            nodes: c.tree().nodes.len(),
            bytes,
            load_s: loaded.load_s,
            build_s: loaded.build_s,
            prepare_s: loaded.prepare_s,
            write_s,
        })?;
    } else {
        eprintln!(
            "{}: {} triangles, {} nodes, {bytes} bytes (load {:.3} s, build {:.3} s, write {write_s:.3} s)",
            a.out.display(),
            c.scene.triangles.len(),
            c.tree().nodes.len(),
            loaded.load_s,
            loaded.build_s
        );
    }
    Ok(ExitCode::SUCCESS)
}
