//! kdtrace host: scene loading (OBJ, TOML scene files, compiled `.kdc` scenes), k-d tree
//! construction, the CPU reference renderer, the wgpu runner for the rust-gpu kernel, image
//! output and the CPU ≡ GPU check.
// The k-d builder compares sixteen events at once (`kdbuild::sah`), as the shared crate's leaf
// test tests eight triangles; the pinned nightly has `core::simd`.
#![feature(portable_simd)]
pub mod camera;
pub mod cpu;
pub mod files;
pub mod gpu;
pub mod image_io;
pub mod kdbuild;
pub mod kdc;
pub mod local_frame;
pub mod metrics;
pub mod obj;
pub mod procedural;
pub mod raybench;
pub mod render;
pub mod scene;
pub mod scene_file;
pub mod scene_settings;
pub mod transform;
pub mod verify;

use anyhow::{bail, Result};
use scene_settings::SceneSettings;
use std::path::Path;
use std::time::Instant;

/// A loaded and compiled scene with the time each step took.
pub struct Loaded {
    pub compiled: render::Compiled,
    /// What the scene file (or the `.kdc`) says about rendering; empty for a bare OBJ.
    pub settings: SceneSettings,
    /// Problems that did not stop the load (missing MTL, dropped degenerate geometry, …).
    pub warnings: Vec<String>,
    pub kind: SceneKind,
    /// Reading and parsing (for a `.kdc`: reading, checking and validating everything).
    pub load_s: f64,
    /// Building the k-d tree (0 for a `.kdc`).
    pub build_s: f64,
    /// Laying the scene out for rendering once its tree is built: unit normals and the CPU's
    /// eight-triangle leaf blocks (`render::Compiled::new`; for a `.kdc`, part of `load_s`).
    pub prepare_s: f64,
}

/// The scene formats `load` accepts, by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneKind {
    Obj,
    Toml,
    Kdc,
}

impl SceneKind {
    pub fn of(path: &Path) -> Result<Self> {
        let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
        Ok(match ext.as_deref() {
            Some("obj") => SceneKind::Obj,
            Some("toml") => SceneKind::Toml,
            Some("kdc") => SceneKind::Kdc,
            _ => bail!("{}: unknown scene type (expected .obj, .toml or .kdc)", path.display()),
        })
    }
}

/// Loads a scene by its extension: an OBJ or a TOML scene file is parsed and its k-d tree built
/// with `settings`; a `.kdc` is read as compiled (its tree was built with the settings stored in
/// it, and `settings` is not used).
pub fn load(path: &Path, settings: kdbuild::BuildSettings) -> Result<Loaded> {
    let t0 = Instant::now();
    let kind = SceneKind::of(path)?;
    let (scene, scene_settings, mut warnings) = match kind {
        SceneKind::Kdc => {
            let k = kdc::read(path)?;
            return Ok(Loaded {
                compiled: k.compiled,
                settings: k.settings,
                warnings: Vec::new(),
                kind,
                load_s: t0.elapsed().as_secs_f64(),
                build_s: 0.0,
                prepare_s: 0.0,
            });
        }
        SceneKind::Obj => {
            let mesh = obj::load_mesh(path, &files::Disk)?;
            let scene = scene::Scene::new(mesh.triangles, mesh.material_of, mesh.materials, mesh.material_names)
                .map_err(|e| e.context(path.display().to_string()))?;
            (scene, SceneSettings::default(), mesh.warnings)
        }
        SceneKind::Toml => {
            let r = scene_file::load(path, &files::Disk)?;
            (r.scene, r.settings, r.warnings)
        }
    };
    if scene.dropped_degenerate > 0 {
        warnings.push(format!("{}: {} zero-area triangles dropped", path.display(), scene.dropped_degenerate));
    }
    let load_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let (scene, origin) = local_frame::to_local(scene);
    let tree = kdbuild::build(&scene.triangles, scene.bounds_min, scene.bounds_max, settings);
    let build_s = t1.elapsed().as_secs_f64();
    let t2 = Instant::now();
    let mut compiled = render::Compiled::new(scene, tree);
    compiled.origin = origin;
    let prepare_s = t2.elapsed().as_secs_f64();
    Ok(Loaded { compiled, settings: scene_settings, warnings, kind, load_s, build_s, prepare_s })
}

/// Builds a scene's k-d tree, in the scene's own coordinates (`load` first moves a scene far from
/// the origin next to it: `local_frame`).
pub fn compile(scene: scene::Scene, settings: kdbuild::BuildSettings) -> render::Compiled {
    let tree = kdbuild::build(&scene.triangles, scene.bounds_min, scene.bounds_max, settings);
    render::Compiled::new(scene, tree)
}
