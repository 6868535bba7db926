//! Wavefront OBJ + MTL loading through tobj: faces are fan-triangulated, `Kd` becomes the
//! diffuse albedo, `Ke` the one-sided emission, `illum` 3/5 a mirror and 4/6/7 glass
//! (`mtl_material`); a mesh without a material is grey diffuse.
//!
//! tobj accepts `nan`, `inf` and `1e39` coordinates and reports errors without a line, so the
//! vertex lines are checked here first, and every error names the file (and line where it can):
//! the OBJ, or the MTL library a material or texture came from. Point (`p`) and line (`l`)
//! elements are skipped and counted; zero-area triangles are dropped and counted by
//! [`Scene::new`]. Both counts come back as warnings, never silently.
//!
//! Format reference: Wavefront's "Object Files (.obj)" and "MTL material format" appendices
//! (<https://paulbourke.net/dataformats/obj/>, <https://paulbourke.net/dataformats/mtl/>).
use crate::files::{Disk, Files};
use crate::scene::{conductor, dielectric, diffuse, principled, Principled, Scene, WorldScene};
use anyhow::{anyhow, bail, Context, Result};
use shared::glam::{DVec3, Vec3};
use std::borrow::Cow;
use std::cell::RefCell;
use std::io::{Cursor, ErrorKind};
use std::path::{Path, PathBuf};

/// Albedo of meshes that have no material (Mitsuba's `diffuse` default).
pub const DEFAULT_ALBEDO: f32 = 0.5;
/// Coordinates beyond this are rejected: squared distances would overflow f32.
pub const MAX_COORDINATE: f32 = 1e18;

/// One OBJ file: its triangles with a material each in world coordinates as written (f64), the
/// MTL materials in library order and then the grey default (always last); before they become
/// (part of) a scene.
#[derive(Clone, Debug)]
pub struct Mesh {
    pub scene: WorldScene,
    /// Things the user should know that do not stop the load (missing MTL, skipped elements).
    pub warnings: Vec<String>,
}

/// What the line scan learns besides rejecting bad vertices.
struct Scan {
    /// Point and line elements, and faces of fewer than three corners.
    skipped_elements: usize,
    /// Whether there are `p` or `l` lines: tobj 4 reads an `l` of three or more vertices as a
    /// polygon, so they are blanked out before tobj sees the text.
    has_point_or_line_statements: bool,
}

/// Checks every `v` line for three finite, representable coordinates and counts `p`/`l`
/// elements.
fn scan_lines(path: &Path, text: &str) -> Result<Scan> {
    let mut scan = Scan { skipped_elements: 0, has_point_or_line_statements: false };
    let mut vertices = 0i64;
    for (number, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => vertices += 1,
            Some("f") => {
                // Each corner is v, v/vt, v//vn or v/vt/vn; v counts from 1, or back from the
                // latest vertex when negative (so it must name a vertex defined above).
                let corners: Vec<&str> = words.collect();
                if corners.len() < 3 {
                    scan.skipped_elements += 1;
                }
                for corner in corners {
                    // Every part present must be an index (tobj reports a bad one without a line).
                    let parts: Vec<&str> = corner.split('/').collect();
                    let v = parts[0];
                    if parts.len() > 3 || parts[1..].iter().any(|p| !p.is_empty() && p.parse::<i64>().is_err()) {
                        bail!(
                            "{}:{}: face corner {corner:?} is not v, v/vt, v//vn or v/vt/vn",
                            path.display(),
                            number + 1
                        );
                    }
                    let i = v.parse::<i64>().map_err(|_| {
                        anyhow!(
                            "{}:{}: face corner {corner:?}: {v:?} is not a vertex index",
                            path.display(),
                            number + 1
                        )
                    })?;
                    if i == 0 || i > vertices || i < -vertices {
                        bail!(
                            "{}:{}: face vertex index {i} out of range ({vertices} vertices defined above)",
                            path.display(),
                            number + 1
                        );
                    }
                }
                continue;
            }
            Some("p") => {
                scan.skipped_elements += words.count();
                scan.has_point_or_line_statements = true;
                continue;
            }
            Some("l") => {
                scan.skipped_elements += 1;
                scan.has_point_or_line_statements = true;
                continue;
            }
            _ => continue,
        }
        let values: Vec<&str> = words.collect();
        // (`vertices` already counts this line.) x y z, x y z w, or x y z r g b (the common
        // vertex-colour extension); tobj reports any other count without a line.
        if !matches!(values.len(), 3 | 4 | 6) {
            bail!(
                "{}:{}: vertex needs 3 coordinates (4 with w, 6 with a colour), not {}: {line:?}",
                path.display(),
                number + 1,
                values.len()
            );
        }
        let coords = &values[..3];
        for c in coords {
            let c = *c;
            let x: f64 = c.parse().map_err(|_| anyhow!("{}:{}: not a number: {c:?}", path.display(), number + 1))?;
            if !x.is_finite() || x.abs() > MAX_COORDINATE as f64 {
                bail!("{}:{}: coordinate {c} is not finite or beyond ±{MAX_COORDINATE:e}", path.display(), number + 1);
            }
        }
    }
    Ok(scan)
}

/// An MTL material as one of ours: `illum` 3 or 5 (a ray-traced mirror) becomes a smooth
/// conductor reflecting `Ks` at normal incidence (η = 1 and κ = 2√(Ks/(1 − Ks)) per channel,
/// whose Fresnel reflectance at normal incidence is Ks; Ks ≥ 1 a perfect mirror); 4, 6 and 7
/// (glass) a smooth dielectric of index `Ni` (1.5 when absent; `Tf` and `Ks` tints are not
/// modelled). Any other: with the PBR extension's `Pr` (roughness) or `Pm` (metallic), a
/// principled material of base colour `Kd`, index `Ni` (default 1.5), roughness `Pr` (default
/// 0.5) and metallic `Pm` (default 0); with a non-black `Ks`, a principled dielectric whose
/// specular lobe reflects Ks at normal incidence (its luminance, at most 0.96, as F0, so
/// η = (1 + √F0)/(1 − √F0)) with the GGX α of a Phong exponent `Ns`, √(2/(Ns + 2)) (Walter et
/// al. 2007's Phong–Beckmann correspondence), over the Lambertian `Kd`: the coating takes from
/// the diffuse what it reflects, so Kd + Ks > 1 stays energy-conserving; else Lambertian `Kd`.
/// `Ke` emits from every kind.
fn mtl_material(m: &tobj::Material, kd: Vec3, ke: Vec3) -> shared::layout::Material {
    match m.illumination_model {
        Some(3 | 5) => {
            let ks = m.specular.map_or(Vec3::ONE, |c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32));
            if ks.min_element() >= 1.0 {
                return conductor(Vec3::ZERO, Vec3::ONE, 0.0, ke);
            }
            let k = ks.min(Vec3::splat(0.999_999)).max(Vec3::ZERO);
            let kappa = Vec3::new(
                2.0 * (k.x / (1.0 - k.x)).sqrt(),
                2.0 * (k.y / (1.0 - k.y)).sqrt(),
                2.0 * (k.z / (1.0 - k.z)).sqrt(),
            );
            conductor(Vec3::ONE, kappa, 0.0, ke)
        }
        Some(4 | 6 | 7) => {
            let ni = m.optical_density.filter(|n| n.is_finite() && *n > 0.0).unwrap_or(1.5);
            dielectric(ni as f32, 0.0, ke)
        }
        _ => {
            // `check_mtl_lines` has checked that these parse and lie within 0..=1.
            let pbr = |key: &str| m.unknown_param.get(key).and_then(|v| v.trim().parse::<f32>().ok());
            let (pr, pm) = (pbr("Pr"), pbr("Pm"));
            let ks = m.specular.map_or(Vec3::ZERO, |c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32));
            if pr.is_some() || pm.is_some() {
                let ni = m.optical_density.filter(|n| n.is_finite() && (1e-3..=100.0).contains(n)).unwrap_or(1.5);
                let p = Principled {
                    base_color: kd,
                    metallic: pm.unwrap_or(0.0),
                    roughness: pr.unwrap_or(0.5),
                    transmission: 0.0,
                    ior: ni as f32,
                };
                principled(&p, ke)
            } else if ks.max_element() > 0.0 {
                principled(&phong_specular(kd, ks, m.shininess.unwrap_or(0.0) as f32), ke)
            } else {
                diffuse(kd, ke)
            }
        }
    }
}

/// The principled dielectric `mtl_material` makes of `Kd`, `Ks` and `Ns` (documented there).
pub fn phong_specular(kd: Vec3, ks: Vec3, ns: f32) -> Principled {
    let f0 = shared::vecmath::luminance(ks).clamp(0.0, 0.96);
    let r = f0.sqrt();
    let alpha = (2.0 / (ns.max(0.0) + 2.0)).sqrt();
    Principled { base_color: kd, metallic: 0.0, roughness: alpha.sqrt(), transmission: 0.0, ior: (1.0 + r) / (1.0 - r) }
}

/// Checks that every colour statement (`Ka`, `Kd`, `Ks`, `Ke`) has three numbers: tobj 4
/// panics on fewer (found by the `obj_mtl` fuzz target), and a line number helps anyway.
/// Also: exactly three (a fourth is an error, not dropped), and `Kd` within 0..=1 in each channel,
/// the rule a scene file's albedo follows (more would reflect more light than arrives).
fn check_mtl_lines(path: &Path, text: &str) -> Result<()> {
    let mut material = "";
    for (number, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("");
        let mut words = line.split_whitespace();
        let key = words.next();
        if key == Some("newmtl") {
            material = words.next().unwrap_or("");
            continue;
        }
        if let Some(key @ ("Pr" | "Pm" | "Ns")) = key {
            let values: Vec<&str> = words.collect();
            let x = values.first().and_then(|v| v.parse::<f32>().ok());
            let ok = match (values.len(), x) {
                (1, Some(x)) if key == "Ns" => x.is_finite() && x >= 0.0,
                (1, Some(x)) => (0.0..=1.0).contains(&x),
                _ => false,
            };
            if !ok {
                let range = if key == "Ns" { "finite and non-negative" } else { "within 0..=1" };
                bail!(
                    "{}:{}: material {material:?}: {key} needs one number, {range}: {line:?}",
                    path.display(),
                    number + 1
                );
            }
            continue;
        }
        let Some(key @ ("Ka" | "Kd" | "Ks" | "Ke")) = key else { continue };
        let values: Vec<&str> = words.collect();
        let numbers: Vec<f32> = values.iter().filter_map(|v| v.parse().ok()).collect();
        if values.len() != 3 || numbers.len() != 3 {
            bail!("{}:{}: {key} needs three numbers, no more: {line:?}", path.display(), number + 1);
        }
        if numbers.iter().any(|x| !x.is_finite() || *x < 0.0) || (key == "Kd" && numbers.iter().any(|x| *x > 1.0)) {
            let range = if key == "Kd" { "within 0..=1 in each channel" } else { "finite and non-negative" };
            bail!("{}:{}: material {material:?}: {key} {numbers:?} must be {range}", path.display(), number + 1);
        }
    }
    Ok(())
}

/// A warning for each material that `usemtl` names but no library defines (its faces render
/// grey diffuse), with the first line that names it.
fn undefined_materials(path: &Path, text: &str, defined: &[String]) -> Vec<String> {
    let mut named: Vec<&str> = Vec::new();
    let mut out = Vec::new();
    for (number, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() != Some("usemtl") {
            continue;
        }
        let name = words.next().unwrap_or("");
        if !name.is_empty() && !defined.iter().any(|d| d == name) && !named.contains(&name) {
            named.push(name);
            out.push(format!(
                "{}:{}: usemtl {name:?}: no material library defines it (names are case-sensitive); its faces \
                 are grey diffuse",
                path.display(),
                number + 1
            ));
        }
    }
    out
}

/// Classic Mac line ends (a CR alone) read as line breaks like every other line end: tobj and
/// `str::lines` split at LF only and would see the whole file as one line.
fn with_line_feeds(text: Cow<'_, str>) -> Cow<'_, str> {
    let b = text.as_bytes();
    if b.iter().enumerate().any(|(i, &c)| c == b'\r' && b.get(i + 1) != Some(&b'\n')) {
        Cow::Owned(text.replace("\r\n", "\n").replace('\r', "\n"))
    } else {
        text
    }
}

/// The text with every `p` and `l` statement replaced by an empty line (line numbers kept).
fn without_points_and_lines(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        if !matches!(line.split_whitespace().next(), Some("p" | "l")) {
            out.push_str(line);
        }
        out.push('\n');
    }
    out
}

/// Loads an OBJ file as a scene of its own, in world coordinates rounded to f32 (no local frame:
/// for tests and tools that want the file's own coordinates).
pub fn load_obj(path: &Path) -> Result<Scene> {
    let mesh = load_mesh(path, &Disk)?;
    let m = mesh.scene;
    let triangles = m.triangles.iter().map(crate::scene::round_triangle).collect();
    Scene::new(triangles, m.material_of, m.materials, m.material_names).with_context(|| format!("{}", path.display()))
}

/// Reads and parses an OBJ file and the MTL libraries it names.
pub fn load_mesh(path: &Path, files: &dyn Files) -> Result<Mesh> {
    let bytes = files.read(path).map_err(|e| anyhow!("{}: cannot read: {e}", path.display()))?;
    parse_mesh(path, &bytes, files)
}

/// The texture file named by an MTL `map_*` value: its last word (options such as `-bm 1` come
/// first).
fn texture_file(value: &str) -> Option<&str> {
    value.split_whitespace().last()
}

/// Parses OBJ text; `path` names it in messages and locates the MTL libraries through `files`.
pub fn parse_mesh(path: &Path, bytes: &[u8], files: &dyn Files) -> Result<Mesh> {
    // tobj reads lines as UTF-8 and fails the whole file on one bad byte; OBJ is ASCII, so
    // replacement characters only ever land in names and comments.
    let text = with_line_feeds(String::from_utf8_lossy(crate::files::without_bom(bytes)));
    let scan = scan_lines(path, &text)?;
    let text = if scan.has_point_or_line_statements { without_points_and_lines(&text).into() } else { text };
    let dir = path.parent().unwrap_or(Path::new(""));
    let mut warnings = Vec::new();
    // tobj merges the libraries in the order it meets them; remember which file each range of
    // materials came from so that errors can name it.
    let libraries: RefCell<Vec<(PathBuf, usize)>> = RefCell::new(Vec::new());
    let problems: RefCell<Vec<anyhow::Error>> = RefCell::new(Vec::new());
    let missing: RefCell<Vec<PathBuf>> = RefCell::new(Vec::new());
    let loader = |name: &Path| -> tobj::MTLLoadResult {
        let full = dir.join(name);
        let bytes = match files.read(&full) {
            Ok(b) => b,
            Err(e) if e.kind() == ErrorKind::NotFound => {
                missing.borrow_mut().push(full);
                return Err(tobj::LoadError::OpenFileFailed);
            }
            Err(e) => {
                problems.borrow_mut().push(anyhow!("{}: cannot read material library: {e}", full.display()));
                return Err(tobj::LoadError::OpenFileFailed);
            }
        };
        let text = with_line_feeds(String::from_utf8_lossy(crate::files::without_bom(&bytes)));
        if let Err(e) = check_mtl_lines(&full, &text) {
            problems.borrow_mut().push(e);
            return Err(tobj::LoadError::MaterialParseError);
        }
        let result = tobj::load_mtl_buf(&mut Cursor::new(text.as_bytes()));
        match &result {
            Ok((mats, _)) => libraries.borrow_mut().push((full, mats.len())),
            Err(e) => problems.borrow_mut().push(anyhow!("{}: material library: {e}", full.display())),
        }
        result
    };
    let options = tobj::LoadOptions { triangulate: true, single_index: false, ignore_points: true, ignore_lines: true };
    let (models, materials) = tobj::load_obj_buf(&mut Cursor::new(text.as_bytes()), &options, loader)
        .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    if let Some(e) = problems.into_inner().into_iter().next() {
        return Err(e.context(format!("{}: loading its material libraries", path.display())));
    }
    let missing = missing.into_inner();
    for m in &missing {
        warnings.push(format!(
            "{}: material library not found ({}); its materials are grey diffuse",
            path.display(),
            m.display()
        ));
    }
    // A library that failed to open leaves `Err` here only when no other library loaded.
    let mtl = materials.unwrap_or_default();
    let mut source = Vec::with_capacity(mtl.len());
    for (file, count) in libraries.into_inner() {
        source.extend(std::iter::repeat_n(file, count));
    }
    let mut mats = Vec::with_capacity(mtl.len() + 1);
    let mut names = Vec::with_capacity(mtl.len() + 1);
    let mut textures = 0;
    for (i, m) in mtl.iter().enumerate() {
        let library = source.get(i).map(|p| p.as_path()).unwrap_or(path);
        let kd = m.diffuse.map_or([DEFAULT_ALBEDO; 3], |c| c.map(|x| x as f32));
        let ke = m.emissive.map_or([0.0; 3], |c| c.map(|x| x as f32));
        for (what, v) in [("Kd", kd), ("Ke", ke)] {
            if v.iter().any(|x| !x.is_finite() || *x < 0.0 || *x > MAX_COORDINATE) {
                bail!("{}: material {:?}: {what} {v:?} must be finite and non-negative", library.display(), m.name);
            }
        }
        let maps = [
            &m.diffuse_texture,
            &m.ambient_texture,
            &m.specular_texture,
            &m.normal_texture,
            &m.shininess_texture,
            &m.dissolve_texture,
        ];
        for value in maps.into_iter().flatten() {
            let Some(file) = texture_file(value) else { continue };
            let full = library.parent().unwrap_or(Path::new("")).join(file);
            if !files.exists(&full) {
                bail!("{}: material {:?}: texture {file:?} not found ({})", library.display(), m.name, full.display());
            }
            textures += 1;
        }
        mats.push(mtl_material(m, Vec3::from(kd), Vec3::from(ke)));
        names.push(m.name.clone());
    }
    if textures > 0 {
        warnings.push(format!(
            "{}: {textures} texture maps ignored (textures are not supported yet; Kd is used)",
            path.display()
        ));
    }
    if missing.is_empty() {
        warnings.extend(undefined_materials(path, &text, &names));
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
        let vertex = |i: u32| -> Result<DVec3> {
            let i = i as usize;
            match mesh.positions.get(3 * i..3 * i + 3) {
                Some(p) => Ok(DVec3::new(p[0], p[1], p[2])),
                None => bail!(
                    "{}: object {:?}: vertex index {} out of range ({} vertices)",
                    path.display(),
                    model.name,
                    i + 1,
                    mesh.positions.len() / 3
                ),
            }
        };
        for f in mesh.indices.as_chunks::<3>().0 {
            triangles.push([vertex(f[0])?, vertex(f[1])?, vertex(f[2])?]);
            material_of.push(material);
        }
    }
    if triangles.is_empty() {
        bail!("{}: no triangles", path.display());
    }
    if scan.skipped_elements > 0 {
        warnings.push(format!(
            "{}: {} point and line elements skipped (only faces are rendered)",
            path.display(),
            scan.skipped_elements
        ));
    }
    Ok(Mesh { scene: WorldScene { triangles, material_of, materials: mats, material_names: names }, warnings })
}
