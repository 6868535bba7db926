//! Wavefront OBJ + MTL loading through tobj: faces are fan-triangulated, `Kd` becomes the
//! diffuse albedo, `Ke` the one-sided emission, `illum` 3/5 a mirror and 4/6/7 glass
//! (`mtl_material`); a mesh without a material is grey diffuse.
//!
//! Surfaces: `vt` texture coordinates and `vn` vertex normals (`WorldAttributes`), and the
//! texture maps `map_Kd` (albedo, sRGB), `map_Ke` (emission, sRGB; the material's constant
//! emission becomes the texture's mean, which weighs it in the light table), `map_d` (alpha
//! mask, linear), and the PBR extension keys `map_Pr` (perceptual roughness r, α = r²) and
//! `map_Pm` (metallic), each replacing the constant it covers (`shared::surface::resolve`). A
//! constant dissolve `d` (or `Tr` = 1 − d) below 0.5 cuts the material's faces out entirely,
//! the same threshold as a mask (glass, `illum` 4/6/7, ignores it: it is transparent by its
//! own model). `map_Ka`, `map_Ks`, `map_Ns` and bump maps are checked to exist and ignored,
//! with a warning.
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
use crate::scene::texture::{Kind, TextureSet};
use crate::scene::{conductor, dielectric, diffuse, principled, Principled, Scene, WorldAttributes, WorldScene};
use anyhow::{anyhow, bail, Context, Result};
use shared::glam::{DVec3, Vec3};
use shared::layout::{TEXTURE_ALBEDO, TEXTURE_ALPHA, TEXTURE_EMISSION, TEXTURE_METALLIC, TEXTURE_ROUGHNESS};
use std::borrow::Cow;
use std::cell::RefCell;
use std::collections::HashMap;
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
    /// For each triangle the faces become (a face of n corners: n − 2, in file order, as tobj
    /// fan-triangulates them), whether its face gives texture coordinates and normals: tobj
    /// gives a corner without them the previous corner's, which is not the face's own.
    face_attributes: Vec<(bool, bool)>,
}

/// Checks every `v` line for three finite, representable coordinates and counts `p`/`l`
/// elements.
fn scan_lines(path: &Path, text: &str) -> Result<Scan> {
    let mut scan = Scan { skipped_elements: 0, has_point_or_line_statements: false, face_attributes: Vec::new() };
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
                } else {
                    let part = |c: &str, k: usize| c.split('/').nth(k).is_some_and(|p| !p.is_empty());
                    let vt = corners.iter().all(|c| part(c, 1));
                    let vn = corners.iter().all(|c| part(c, 2));
                    scan.face_attributes.extend(std::iter::repeat_n((vt, vn), corners.len() - 2));
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
            Some(key @ ("vt" | "vn")) => {
                // u [v [w]] or x y z: finite numbers (tobj reports a bad one without a line).
                let values: Vec<&str> = words.collect();
                let counts = if key == "vt" { 1..=3 } else { 3..=3 };
                if !counts.contains(&values.len()) {
                    bail!(
                        "{}:{}: {key} needs {counts:?} numbers, not {}: {line:?}",
                        path.display(),
                        number + 1,
                        values.len()
                    );
                }
                for c in values {
                    let x: f64 =
                        c.parse().map_err(|_| anyhow!("{}:{}: not a number: {c:?}", path.display(), number + 1))?;
                    if !x.is_finite() || x.abs() > MAX_COORDINATE as f64 {
                        bail!(
                            "{}:{}: {key} value {c} is not finite or beyond ±{MAX_COORDINATE:e}",
                            path.display(),
                            number + 1
                        );
                    }
                }
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
/// modelled). Any other: with the PBR extension's `Pr` (roughness) or `Pm` (metallic), or their
/// maps `map_Pr`, `map_Pm` (which replace them at each hit), a
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
            let maps = m.unknown_param.contains_key("map_Pr") || m.unknown_param.contains_key("map_Pm");
            let ks = m.specular.map_or(Vec3::ZERO, |c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32));
            if pr.is_some() || pm.is_some() || maps {
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

/// The MTL keys whose line an error names (texture maps and dissolve).
const LINE_KEYS: [&str; 7] = ["map_Kd", "map_d", "map_Ke", "map_Pr", "map_Pm", "d", "Tr"];

/// (material, key) → 1-based line of a statement.
type KeyLines = HashMap<(String, String), usize>;

/// The line of each `LINE_KEYS` statement in an MTL text.
fn key_lines(text: &str) -> KeyLines {
    let mut material = String::new();
    let mut out = HashMap::new();
    for (number, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("newmtl") => material = words.next().unwrap_or("").to_string(),
            Some(key) if LINE_KEYS.contains(&key) => {
                out.insert((material.clone(), key.to_string()), number + 1);
            }
            _ => {}
        }
    }
    out
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
    let attributes = m.attributes.iter().map(WorldAttributes::round).collect();
    Scene::with_surfaces(triangles, m.material_of, m.materials, m.material_names, attributes, &m.textures.textures)
        .with_context(|| format!("{}", path.display()))
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
    let lines: RefCell<HashMap<PathBuf, KeyLines>> = RefCell::new(HashMap::new());
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
        lines.borrow_mut().insert(full.clone(), key_lines(&text));
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
    let mut textures = TextureSet::default();
    // Materials whose constant dissolve cuts their faces out.
    let mut invisible = vec![false; mtl.len() + 1];
    let mut ignored = 0;
    let lines = lines.into_inner();
    for (i, m) in mtl.iter().enumerate() {
        let library = source.get(i).map(|p| p.as_path()).unwrap_or(path);
        let kd = m.diffuse.map_or([DEFAULT_ALBEDO; 3], |c| c.map(|x| x as f32));
        let ke = m.emissive.map_or([0.0; 3], |c| c.map(|x| x as f32));
        for (what, v) in [("Kd", kd), ("Ke", ke)] {
            if v.iter().any(|x| !x.is_finite() || *x < 0.0 || *x > MAX_COORDINATE) {
                bail!("{}: material {:?}: {what} {v:?} must be finite and non-negative", library.display(), m.name);
            }
        }
        // `file:line` of a key of this material, or the file where the line is unknown.
        let at = |key: &str| match lines.get(library).and_then(|l| l.get(&(m.name.clone(), key.to_string()))) {
            Some(n) => format!("{}:{n}", library.display()),
            None => library.display().to_string(),
        };
        let dir = library.parent().unwrap_or(Path::new(""));
        for value in
            [&m.ambient_texture, &m.specular_texture, &m.normal_texture, &m.shininess_texture].into_iter().flatten()
        {
            let Some(file) = texture_file(value) else { continue };
            let full = dir.join(file);
            if !files.exists(&full) {
                bail!("{}: material {:?}: texture {file:?} not found ({})", library.display(), m.name, full.display());
            }
            ignored += 1;
        }
        let mut mat = mtl_material(m, Vec3::from(kd), Vec3::from(ke));
        let extension = |key: &str| m.unknown_param.get(key).cloned();
        let maps = [
            ("map_Kd", m.diffuse_texture.clone(), TEXTURE_ALBEDO, Kind::Colour),
            ("map_d", m.dissolve_texture.clone(), TEXTURE_ALPHA, Kind::Alpha),
            ("map_Ke", extension("map_Ke"), TEXTURE_EMISSION, Kind::Colour),
            ("map_Pr", extension("map_Pr"), TEXTURE_ROUGHNESS, Kind::Value),
            ("map_Pm", extension("map_Pm"), TEXTURE_METALLIC, Kind::Value),
        ];
        for (key, value, slot, kind) in maps {
            let Some(file) = value.as_deref().and_then(texture_file) else { continue };
            let wanted_by = format!("{}: material {:?}: {key} {file:?}", at(key), m.name);
            mat.textures[slot] = textures.load(files, &dir.join(file), kind, &wanted_by)?;
        }
        if mat.textures[TEXTURE_EMISSION] != shared::layout::NO_TEXTURE {
            let mean = textures.textures[mat.textures[TEXTURE_EMISSION] as usize - 1].mean_rgb();
            mat.emission = Vec3::from(mean).extend(0.0);
        }
        // Constant dissolve: `d`, or `Tr` (transparency, 1 − d) where no `d` is given.
        let dissolve = match (m.dissolve, extension("Tr")) {
            (Some(d), _) => Some((d, "d")),
            (None, Some(tr)) => {
                let tr: f64 = tr
                    .trim()
                    .parse()
                    .map_err(|_| anyhow!("{}: material {:?}: Tr {tr:?} is not a number", at("Tr"), m.name))?;
                Some((1.0 - tr, "Tr"))
            }
            (None, None) => None,
        };
        if let Some((d, key)) = dissolve {
            if !(0.0..=1.0).contains(&d) {
                bail!("{}: material {:?}: {key} gives dissolve {d}, not within 0..=1", at(key), m.name);
            }
            let glass = matches!(m.illumination_model, Some(4 | 6 | 7));
            invisible[i] = d < shared::layout::ALPHA_CUTOFF as f64 && !glass;
        }
        mats.push(mat);
        names.push(m.name.clone());
    }
    if ignored > 0 {
        warnings.push(format!(
            "{}: {ignored} texture maps ignored (map_Ka, map_Ks, map_Ns and bump maps are not supported)",
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
    let mut attributes = Vec::new();
    let mut cut = 0usize;
    let faces = &scan.face_attributes;
    let surfaces = faces.iter().any(|&(vt, vn)| vt || vn);
    // Each triangle's face, when tobj made as many triangles as the faces promise; otherwise
    // (never seen) attributes only where every face has them.
    let per_face = faces.len() == models.iter().map(|m| m.mesh.indices.len() / 3).sum::<usize>();
    let every = (faces.iter().all(|f| f.0), faces.iter().all(|f| f.1));
    if surfaces && !per_face {
        warnings.push(format!(
            "{}: faces and triangles do not match up; texture coordinates and vertex normals are used only where \
             every face has them",
            path.display()
        ));
    }
    let mut triangle = 0;
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
        // tobj gives a corner without vt or vn the previous corner's (its documented fallback),
        // so the index lists are as long as the positions' whenever the file has any; the
        // scan says which faces really have them.
        let uvs = mesh.texcoord_indices.len() == mesh.indices.len();
        let normals = mesh.normal_indices.len() == mesh.indices.len();
        for (k, f) in mesh.indices.as_chunks::<3>().0.iter().enumerate() {
            let (has_uv, has_normals) = if per_face { faces[triangle] } else { every };
            triangle += 1;
            if invisible[material as usize] {
                cut += 1;
                continue;
            }
            triangles.push([vertex(f[0])?, vertex(f[1])?, vertex(f[2])?]);
            material_of.push(material);
            if !surfaces {
                continue;
            }
            let mut a = WorldAttributes::default();
            for j in 0..3 {
                let corner = 3 * k + j;
                if uvs && has_uv {
                    let t = mesh.texcoord_indices[corner] as usize;
                    if let Some(uv) = mesh.texcoords.get(2 * t..2 * t + 2) {
                        a.uv[j] = [uv[0], uv[1]];
                    }
                }
                if normals && has_normals {
                    let n = mesh.normal_indices[corner] as usize;
                    if let Some(n) = mesh.normals.get(3 * n..3 * n + 3) {
                        a.normals[j] = DVec3::new(n[0], n[1], n[2]);
                    }
                }
            }
            // Unit normals, or none for the whole triangle when one of them has no direction.
            let lengths = a.normals.map(|n| n.length());
            a.normals = if lengths.iter().all(|l| l.is_finite() && *l > 0.0) {
                [0, 1, 2].map(|j| a.normals[j] / lengths[j])
            } else {
                [DVec3::ZERO; 3]
            };
            attributes.push(a);
        }
    }
    if cut > 0 {
        warnings.push(format!(
            "{}: {cut} faces cut out: their material's dissolve (d, or 1 − Tr) is below {}",
            path.display(),
            shared::layout::ALPHA_CUTOFF
        ));
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
    Ok(Mesh {
        scene: WorldScene {
            triangles,
            material_of,
            materials: mats,
            material_names: names,
            attributes,
            textures,
            ..Default::default()
        },
        warnings,
    })
}
