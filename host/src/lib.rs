//! kdtrace host: scene loading, k-d tree construction, the CPU reference renderer, the wgpu
//! runner for the rust-gpu kernel, image output and the CPU ≡ GPU check.
pub mod camera;
pub mod cpu;
pub mod gpu;
pub mod image_io;
pub mod kdbuild;
pub mod metrics;
pub mod obj;
pub mod procedural;
pub mod render;
pub mod scene;
pub mod verify;

use anyhow::Result;
use std::path::Path;
use std::time::Instant;

/// A loaded and compiled scene with the time each step took.
pub struct Loaded {
    pub compiled: render::Compiled,
    pub load_s: f64,
    pub build_s: f64,
}

/// Loads an OBJ scene and builds its k-d tree.
pub fn load(path: &Path, settings: kdbuild::BuildSettings) -> Result<Loaded> {
    let t0 = Instant::now();
    let scene = obj::load_obj(path)?;
    let load_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let compiled = compile(scene, settings);
    let build_s = t1.elapsed().as_secs_f64();
    Ok(Loaded { compiled, load_s, build_s })
}

/// Builds a scene's k-d tree.
pub fn compile(scene: scene::Scene, settings: kdbuild::BuildSettings) -> render::Compiled {
    let tree = kdbuild::build(&scene.triangles, scene.bounds_min, scene.bounds_max, settings);
    render::Compiled::new(scene, tree)
}
