//! Wavefront OBJ + MTL loading through tobj: faces are fan-triangulated, `Kd` becomes the
//! diffuse albedo, `Ke` the one-sided emission; a mesh without a material is grey diffuse.
//!
//! tobj accepts `nan`, `inf` and `1e39` coordinates and reports errors without a line, so the
//! vertex lines are checked here first, and every error names the file (and line where it can).
use crate::scene::{diffuse, Scene};
use anyhow::{anyhow, bail, Context, Result};
use shared::glam::{Vec3, Vec4};
use shared::layout::Triangle;
use std::path::Path;

/// Albedo of meshes that have no material (Mitsuba's `diffuse` default).
pub const DEFAULT_ALBEDO: f32 = 0.5;
/// Coordinates beyond this are rejected: squared distances would overflow f32.
pub const MAX_COORDINATE: f32 = 1e18;

/// Checks every `v` line for three finite, representable coordinates.
fn check_vertex_lines(path: &Path, text: &str) -> Result<()> {
    for (number, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() != Some("v") {
            continue;
        }
        let coords: Vec<&str> = words.take(3).collect();
        if coords.len() < 3 {
            bail!("{}:{}: vertex needs 3 coordinates: {line:?}", path.display(), number + 1);
        }
        for c in coords {
            let x: f64 = c.parse().map_err(|_| anyhow!("{}:{}: not a number: {c:?}", path.display(), number + 1))?;
            if !x.is_finite() || x.abs() > MAX_COORDINATE as f64 {
                bail!("{}:{}: coordinate {c} is not finite or beyond ±{MAX_COORDINATE:e}", path.display(), number + 1);
            }
        }
    }
    Ok(())
}

pub fn load_obj(path: &Path) -> Result<Scene> {
    let text = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    check_vertex_lines(path, &String::from_utf8_lossy(&text))?;
    let options = tobj::LoadOptions { triangulate: true, single_index: false, ignore_points: true, ignore_lines: true, ..Default::default() };
    let (models, materials) = tobj::load_obj(path, &options).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let mtl = match materials {
        Ok(m) => m,
        // A missing MTL file degrades to grey; a broken one is an error.
        Err(tobj::LoadError::OpenFileFailed) => {
            eprintln!("warning: {}: material library not found; using grey diffuse", path.display());
            Vec::new()
        }
        Err(e) => bail!("{}: material library: {e}", path.display()),
    };
    let mut mats = Vec::with_capacity(mtl.len() + 1);
    let mut names = Vec::with_capacity(mtl.len() + 1);
    for m in &mtl {
        let kd = m.diffuse.unwrap_or([DEFAULT_ALBEDO; 3]);
        let ke = m.emissive.unwrap_or([0.0; 3]);
        for (what, v) in [("Kd", kd), ("Ke", ke)] {
            if v.iter().any(|x| !x.is_finite() || *x < 0.0) {
                bail!("{}: material {:?}: {what} {v:?} must be finite and non-negative", path.display(), m.name);
            }
        }
        mats.push(diffuse(Vec3::from(kd), Vec3::from(ke)));
        names.push(m.name.clone());
    }
    let default_material = mats.len() as u32;
    mats.push(diffuse(Vec3::splat(DEFAULT_ALBEDO), Vec3::ZERO));
    names.push("default".into());

    let mut triangles = Vec::new();
    let mut material_of = Vec::new();
    for model in &models {
        let mesh = &model.mesh;
        let material = match mesh.material_id {
            Some(id) if id < mtl.len() => id as u32,
            _ => default_material,
        };
        let vertex = |i: u32| -> Result<Vec4> {
            let i = i as usize;
            if 3 * i + 2 >= mesh.positions.len() {
                bail!("{}: object {:?}: vertex index {} out of range", path.display(), model.name, i + 1);
            }
            Ok(Vec4::new(mesh.positions[3 * i], mesh.positions[3 * i + 1], mesh.positions[3 * i + 2], 0.0))
        };
        for f in mesh.indices.chunks_exact(3) {
            triangles.push(Triangle { v0: vertex(f[0])?, v1: vertex(f[1])?, v2: vertex(f[2])? });
            material_of.push(material);
        }
    }
    if triangles.is_empty() {
        bail!("{}: no triangles", path.display());
    }
    Scene::new(triangles, material_of, mats, names).with_context(|| format!("{}", path.display()))
}
