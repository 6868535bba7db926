//! Loading a scene by its extension: an OBJ, a glTF (`.gltf`, `.glb`) or a TOML scene file is
//! read, placed in f64, moved to its local frame, rounded to f32 once and its k-d tree built; a
//! `.kdc` is read as compiled.
use super::kdc;
use crate::files;
use crate::kdbuild::{self, BuildSettings};
use crate::render::Compiled;
use crate::scene::{file, gltf_file, obj, Scene};
use crate::settings::SceneSettings;
use anyhow::{bail, Result};
use shared::numerics::{MAX_EXTENT, MIN_EXTENT};
use std::path::Path;
use std::time::Instant;

/// A loaded and compiled scene with the time each step took.
pub struct Loaded {
    pub compiled: Compiled,
    /// What the scene file (or the `.kdc`) says about rendering; empty for a bare OBJ.
    pub settings: SceneSettings,
    /// Problems that did not stop the load (missing MTL, dropped degenerate geometry, …).
    pub warnings: Vec<String>,
    /// A glTF camera's aspect ratio (width / height): a `--width` or `--height` given alone keeps
    /// it (`cli::settings`).
    pub aspect: Option<f64>,
    pub kind: SceneKind,
    /// Reading and parsing (for a `.kdc`: reading, checking and validating everything).
    pub load_s: f64,
    /// Building the k-d tree (0 for a `.kdc`, and for `load_deferred`, which leaves it to be
    /// built when first asked for).
    pub build_s: f64,
    /// Laying the scene out for rendering: unit normals, the light table and, once the tree is
    /// built, the CPU's eight-triangle leaf blocks (`Compiled::new`, `Compiled::deferred`; for a
    /// `.kdc`, part of `load_s`).
    pub prepare_s: f64,
}

/// The scene formats `load` accepts, by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneKind {
    Obj,
    Gltf,
    Toml,
    Kdc,
}

impl SceneKind {
    pub fn of(path: &Path) -> Result<Self> {
        let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
        Ok(match ext.as_deref() {
            Some("obj") => SceneKind::Obj,
            Some("gltf" | "glb") => SceneKind::Gltf,
            Some("toml") => SceneKind::Toml,
            Some("kdc") => SceneKind::Kdc,
            _ => bail!("{}: unknown scene type (expected .obj, .gltf, .glb, .toml or .kdc)", path.display()),
        })
    }
}

/// Loads a scene by its extension: an OBJ or a TOML scene file is parsed and its k-d tree built
/// with `settings`; a `.kdc` is read as compiled (its tree was built with the settings stored in
/// it, and `settings` is not used).
pub fn load(path: &Path, settings: BuildSettings) -> Result<Loaded> {
    load_with_camera(path, settings, None)
}

/// `load`, with a glTF scene's camera chosen by its index or name (`--camera`; default: its first
/// perspective camera). A camera choice for any other kind of scene is an error.
pub fn load_with_camera(path: &Path, settings: BuildSettings, camera: Option<&str>) -> Result<Loaded> {
    load_scene(path, settings, camera, false)
}

/// `load_with_camera`, leaving the k-d tree to be built when first asked for
/// (`Compiled::deferred`; a `.kdc` brings its own): a CPU render on the wide BVH never needs it.
/// `build_s` is then 0.
pub fn load_deferred(path: &Path, settings: BuildSettings, camera: Option<&str>) -> Result<Loaded> {
    load_scene(path, settings, camera, true)
}

fn load_scene(path: &Path, settings: BuildSettings, camera: Option<&str>, defer: bool) -> Result<Loaded> {
    let t0 = Instant::now();
    let kind = SceneKind::of(path)?;
    if camera.is_some() && kind != SceneKind::Gltf {
        bail!("{}: --camera chooses a glTF file's camera; this scene is not a .gltf or .glb file", path.display());
    }
    let mut aspect = None;
    let (scene, scene_settings, mut warnings) = match kind {
        SceneKind::Kdc => {
            let k = kdc::read(path)?;
            if k.compiled.scene.triangles.is_empty() {
                bail!("{}: the compiled scene has no triangles: nothing to render", path.display());
            }
            return Ok(Loaded {
                compiled: k.compiled,
                settings: k.settings,
                warnings: Vec::new(),
                aspect: None,
                kind,
                load_s: t0.elapsed().as_secs_f64(),
                build_s: 0.0,
                prepare_s: 0.0,
            });
        }
        SceneKind::Obj => {
            let mesh = obj::load_mesh(path, &files::Disk)?;
            (mesh.scene, SceneSettings::default(), mesh.warnings)
        }
        SceneKind::Gltf => {
            let g = gltf_file::load(path, &files::Disk)?;
            let (camera_settings, camera_aspect, camera_warnings) = g.camera_settings(path, camera)?;
            aspect = camera_aspect;
            let mut warnings = g.mesh.warnings;
            warnings.extend(camera_warnings);
            (g.mesh.scene, camera_settings, warnings)
        }
        SceneKind::Toml => {
            let r = file::load(path, &files::Disk)?;
            (r.scene, r.settings, r.warnings)
        }
    };
    let (scene, origin) = scene.into_local().map_err(|e| e.context(path.display().to_string()))?;
    // Every device and command refuses a scene with nothing to hit (a GPU cannot even bind an
    // empty triangle buffer): an error, not a black image.
    if scene.triangles.is_empty() {
        bail!(
            "{}: no renderable triangles (all {} have zero area once placed)",
            path.display(),
            scene.dropped_degenerate
        );
    }
    check_extent(&scene, path)?;
    if scene.dropped_degenerate > 0 {
        warnings.push(format!("{}: {} zero-area triangles dropped", path.display(), scene.dropped_degenerate));
    }
    let load_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let tree = (!defer).then(|| kdbuild::build(&scene.triangles, scene.bounds_min, scene.bounds_max, settings));
    let build_s = t1.elapsed().as_secs_f64();
    let t2 = Instant::now();
    let mut compiled = match tree {
        Some(tree) => Compiled::new(scene, tree),
        None => Compiled::deferred(scene, settings),
    };
    compiled.origin = origin;
    let prepare_s = t2.elapsed().as_secs_f64();
    Ok(Loaded { compiled, settings: scene_settings, warnings, aspect, kind, load_s, build_s, prepare_s })
}

/// The scene's box in its local frame against the range the renderer computes correctly
/// (`shared::numerics::MAX_EXTENT`, `MIN_EXTENT`).
fn check_extent(scene: &Scene, path: &Path) -> Result<()> {
    let (lo, hi) = (scene.bounds_min, scene.bounds_max);
    let reach = lo.abs().max(hi.abs()).max_element();
    let side = (hi - lo).max_element();
    if reach > MAX_EXTENT {
        bail!(
            "{}: the scene reaches {reach:e} units from its local origin; kdtrace renders scenes up to \
             {MAX_EXTENT:e} units (scale it down)",
            path.display()
        );
    }
    if side < MIN_EXTENT {
        bail!(
            "{}: the scene is {side:e} units across; kdtrace renders scenes of at least {MIN_EXTENT:e} units \
             (scale it up)",
            path.display()
        );
    }
    Ok(())
}

/// Builds a scene's k-d tree, in the scene's own coordinates (`load` first moves a scene far from
/// the origin next to it: `local_frame`).
pub fn compile(scene: Scene, settings: BuildSettings) -> Compiled {
    let tree = kdbuild::build(&scene.triangles, scene.bounds_min, scene.bounds_max, settings);
    Compiled::new(scene, tree)
}
