//! The human-written scene file (TOML): camera, render settings, materials, meshes with
//! transforms and material overrides, environment colour. The schema with an example is in the
//! README ("Scene files"); the types below are that schema.
//!
//! TOML (<https://toml.io/en/v1.0.0>) rather than RON: it is what Cargo users already write,
//! it has comments, and its parser reports every error with a byte span, which becomes
//! `file:line:column` here. Unknown keys are errors (`deny_unknown_fields`), so a typo never
//! silently falls back to a default. Every number is checked while it is read (finite, in range),
//! and those checks carry the span of the offending value as well.
mod material;

use material::scene_material;
pub use material::{Alpha, Ior, MaterialKind, MaterialSection, RawMaterial, Unit, DEFAULT_IOR};

use crate::files::Files;
use crate::scene::obj::MAX_COORDINATE;
use crate::scene::texture::{Kind, TextureSet};
use crate::scene::transform::Placement;
use crate::scene::{PunctualLight, WorldAttributes, WorldScene};
use crate::settings::scene::SceneSettings;
use crate::settings::{Connect, SamplerKind, MAX_BOUNCES, MAX_SIDE, MAX_SPP};
use anyhow::{anyhow, bail, Context, Result};
use serde::{Deserialize, Serialize};
use shared::glam::{DMat3, DVec3, Vec3};
use shared::layout::{NO_TEXTURE, TEXTURE_ALBEDO};
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Component, Path, PathBuf};
use toml::Spanned;

/// A whole scene file.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Radiance of rays that leave the scene: a linear RGB colour (default black) or an
    /// environment map `{ file, strength, rotate }`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub environment: Option<Spanned<Environment>>,
    #[serde(default)]
    pub camera: CameraSection,
    #[serde(default)]
    pub render: RenderSection,
    /// Named materials that meshes refer to.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub materials: BTreeMap<String, MaterialSection>,
    #[serde(rename = "mesh", default)]
    pub meshes: Vec<MeshSection>,
    /// Punctual lights (glTF `KHR_lights_punctual`).
    #[serde(rename = "light", default, skip_serializing_if = "Vec::is_empty")]
    pub lights: Vec<Spanned<LightSection>>,
}

/// `environment = [r, g, b]` or `environment = { file = "sky.exr", strength = 1.0, rotate = [x, y, z] }`.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Environment {
    Color(Color),
    Map(EnvironmentSection),
}

impl<'de> Deserialize<'de> for Environment {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let v = toml::Value::deserialize(d)?;
        match v {
            toml::Value::Array(_) => {
                let numbers: Vec<f64> = v.try_into().map_err(|e: toml::de::Error| D::Error::custom(e.message()))?;
                Color::try_from(numbers).map(Environment::Color).map_err(D::Error::custom)
            }
            toml::Value::Table(_) => v
                .try_into()
                .map(Environment::Map)
                .map_err(|e: toml::de::Error| D::Error::custom(format!("environment map: {}", e.message().trim_end()))),
            other => Err(D::Error::custom(format!(
                "environment must be a colour [r, g, b] or a map {{ file = \"sky.exr\", strength = 1.0, rotate = [0, 0, 0] }}, not a {}",
                other.type_str()
            ))),
        }
    }
}

/// An environment map: an equirectangular OpenEXR (`.exr`) or PFM file (relative to the scene
/// file), a factor on its radiance, and Euler angles in degrees (Mitsuba's `to_world` rotation:
/// about X, then Y, then Z).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentSection {
    pub file: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub strength: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotate: Option<Point>,
}

/// A punctual light: `type` "point", "spot" or "directional"; `color` (default white) times
/// `intensity` (candela for point and spot, lux for directional; default 1); `position`
/// (point, spot; default origin), `direction` it shines along (spot, directional; default −Y);
/// spot cone angles in radians as glTF gives them (defaults 0 and π/4).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightSection {
    #[serde(rename = "type")]
    pub kind: LightKind,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position: Option<Point>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub direction: Option<Point>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub color: Option<Color>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intensity: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inner_cone_angle: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub outer_cone_angle: Option<f64>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LightKind {
    Point,
    Spot,
    Directional,
}

impl LightSection {
    /// The light, checked, in world coordinates.
    pub fn light(&self) -> Result<crate::scene::PunctualLight> {
        use crate::scene::PunctualLight;
        let position = self.position.map_or(DVec3::ZERO, Point::dvec3);
        let direction = self.direction.map_or(DVec3::NEG_Y, Point::dvec3);
        let color = self.color.map_or(Vec3::ONE, |c| vec3_of(c.0));
        let intensity = self.intensity.unwrap_or(1.0);
        if !(intensity.is_finite() && intensity >= 0.0 && intensity <= f32::MAX as f64) {
            bail!("intensity {intensity} must be finite and non-negative");
        }
        let intensity = intensity as f32;
        let cone = self.inner_cone_angle.is_some() || self.outer_cone_angle.is_some();
        if cone && self.kind != LightKind::Spot {
            bail!("inner_cone_angle and outer_cone_angle apply to spot lights only");
        }
        if self.position.is_some() && self.kind == LightKind::Directional {
            bail!("a directional light has no position (give its direction)");
        }
        if self.direction.is_some() && self.kind == LightKind::Point {
            bail!("a point light has no direction");
        }
        let l = match self.kind {
            LightKind::Point => PunctualLight::point(position, color, intensity),
            LightKind::Spot => PunctualLight::spot(
                position,
                direction,
                color,
                intensity,
                self.inner_cone_angle.unwrap_or(0.0) as f32,
                self.outer_cone_angle.unwrap_or(std::f64::consts::FRAC_PI_4) as f32,
            ),
            LightKind::Directional => PunctualLight::directional(direction, color, intensity),
        };
        l.check()?;
        Ok(l)
    }
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSection {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eye: Option<Point>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target: Option<Point>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub up: Option<Point>,
    /// Vertical field of view in degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov: Option<Fov>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub width: Option<Side>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height: Option<Side>,
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderSection {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spp: Option<Spp>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bounces: Option<Bounces>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u32>,
    /// "sobol" (default) or "independent".
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sampler: Option<SamplerKind>,
    /// "auto" (default): light subpaths connect to the eye vertices where the scene allows it
    /// and the camera's first hits mostly do not see the light; "on": wherever the scene allows
    /// it; "off": path tracing alone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub connect: Option<Connect>,
    /// Seconds: the render stops between passes of whole samples once they are spent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_limit: Option<Seconds>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSection {
    /// OBJ file, relative to the scene file.
    pub file: Spanned<String>,
    /// Uniform factor or per-axis [x, y, z]; applied first.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<Scale>,
    /// Degrees about the world x, then y, then z axis; applied second.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotate: Option<Point>,
    /// Applied last.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translate: Option<Point>,
    /// A scene material for the whole mesh.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub material: Option<Spanned<String>>,
    /// MTL material name → scene material; wins over `material` for those faces. The name
    /// `default` stands for faces without `usemtl`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub materials: BTreeMap<String, Spanned<String>>,
}

// ---- Values checked while they are read (the error then carries the value's line:column). ----

fn check_coordinate(what: &str, x: f64) -> Result<f32, String> {
    if !x.is_finite() || x.abs() > MAX_COORDINATE as f64 {
        return Err(format!("{what} {x} is not finite or beyond ±{MAX_COORDINATE:e}"));
    }
    Ok(x as f32)
}

/// A finite point or vector, each component within ±1e18.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "Vec<f64>", into = "[f64; 3]")]
pub struct Point(pub [f64; 3]);

/// Exactly three numbers: a fourth is an error, never dropped.
fn three(v: &[f64], what: &str) -> Result<[f64; 3], String> {
    v.try_into().map_err(|_| format!("{what} needs exactly 3 numbers, not {}", v.len()))
}

impl TryFrom<Vec<f64>> for Point {
    type Error = String;
    fn try_from(v: Vec<f64>) -> Result<Self, String> {
        let v = three(&v, "a point or vector")?;
        for x in v {
            check_coordinate("coordinate", x)?;
        }
        Ok(Self(v))
    }
}

impl From<Point> for [f64; 3] {
    fn from(p: Point) -> Self {
        p.0
    }
}

impl Point {
    /// The point as written, in f64 (rounded to f32 only in the scene's local frame).
    pub fn dvec3(self) -> DVec3 {
        DVec3::from(self.0)
    }
}

/// Linear RGB radiance: finite, non-negative.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "Vec<f64>", into = "[f64; 3]")]
pub struct Color(pub [f64; 3]);

impl TryFrom<Vec<f64>> for Color {
    type Error = String;
    fn try_from(v: Vec<f64>) -> Result<Self, String> {
        let v = three(&v, "a colour")?;
        if v.iter().any(|x| !x.is_finite() || *x < 0.0 || *x > MAX_COORDINATE as f64) {
            return Err(format!("colour {v:?} must be finite and non-negative"));
        }
        Ok(Self(v))
    }
}

impl From<Color> for [f64; 3] {
    fn from(c: Color) -> Self {
        c.0
    }
}

/// Reflectance: each channel within 0..=1 (more would create energy).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "Vec<f64>", into = "[f64; 3]")]
pub struct Albedo(pub [f64; 3]);

impl TryFrom<Vec<f64>> for Albedo {
    type Error = String;
    fn try_from(v: Vec<f64>) -> Result<Self, String> {
        let v = three(&v, "an albedo")?;
        if v.iter().any(|x| !(0.0..=1.0).contains(x)) {
            return Err(format!("albedo {v:?} must be within 0..=1 in each channel"));
        }
        Ok(Self(v))
    }
}

impl From<Albedo> for [f64; 3] {
    fn from(c: Albedo) -> Self {
        c.0
    }
}

fn vec3_of(v: [f64; 3]) -> Vec3 {
    Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32)
}

macro_rules! bounded_integer {
    ($name:ident, $what:literal, $lo:expr, $hi:expr) => {
        #[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
        #[serde(try_from = "i64", into = "i64")]
        pub struct $name(pub u32);

        impl TryFrom<i64> for $name {
            type Error = String;
            fn try_from(v: i64) -> Result<Self, String> {
                if v < $lo as i64 || v > $hi as i64 {
                    return Err(format!(concat!($what, " {} must be within {}..={}"), v, $lo, $hi));
                }
                Ok(Self(v as u32))
            }
        }

        impl From<$name> for i64 {
            fn from(v: $name) -> i64 {
                v.0 as i64
            }
        }
    };
}

bounded_integer!(Side, "resolution", 1, MAX_SIDE);
bounded_integer!(Spp, "spp", 1, MAX_SPP);
bounded_integer!(Bounces, "bounces", 0, MAX_BOUNCES);

/// Vertical field of view, strictly between 0 and 180 degrees.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "f64", into = "f64")]
pub struct Fov(pub f64);

impl TryFrom<f64> for Fov {
    type Error = String;
    fn try_from(v: f64) -> Result<Self, String> {
        if !(v > 0.0 && v < 180.0) {
            return Err(format!("field of view {v} must be in (0, 180) degrees"));
        }
        Ok(Self(v))
    }
}

impl From<Fov> for f64 {
    fn from(v: Fov) -> f64 {
        v.0
    }
}

/// A positive, finite number of seconds.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "f64", into = "f64")]
pub struct Seconds(pub f64);

impl TryFrom<f64> for Seconds {
    type Error = String;
    fn try_from(v: f64) -> Result<Self, String> {
        if !(v.is_finite() && v > 0.0) {
            return Err(format!("time limit {v} must be a positive number of seconds"));
        }
        Ok(Self(v))
    }
}

impl From<Seconds> for f64 {
    fn from(v: Seconds) -> f64 {
        v.0
    }
}

/// `scale = 2` or `scale = [1, 2, 1]`: finite, non-zero factors (zero would flatten every face).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "toml::Value", into = "toml::Value")]
pub enum Scale {
    Uniform(f64),
    PerAxis([f64; 3]),
}

fn number(v: &toml::Value) -> Option<f64> {
    match v {
        toml::Value::Float(f) => Some(*f),
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

impl TryFrom<toml::Value> for Scale {
    type Error = String;
    fn try_from(v: toml::Value) -> Result<Self, String> {
        let s = if let Some(x) = number(&v) {
            Scale::Uniform(x)
        } else if let Some(a) = v.as_array().filter(|a| a.len() == 3) {
            let xs: Option<Vec<f64>> = a.iter().map(number).collect();
            let xs = xs.ok_or("scale components must be numbers")?;
            Scale::PerAxis([xs[0], xs[1], xs[2]])
        } else {
            return Err(format!("scale must be a number or [x, y, z], not {v}"));
        };
        if s.factors().iter().any(|x| !x.is_finite() || *x == 0.0 || x.abs() > MAX_COORDINATE as f64) {
            return Err(format!("scale {v} must be finite and non-zero"));
        }
        Ok(s)
    }
}

impl From<Scale> for toml::Value {
    fn from(s: Scale) -> Self {
        match s {
            Scale::Uniform(x) => toml::Value::Float(x),
            Scale::PerAxis(v) => toml::Value::Array(v.iter().map(|x| toml::Value::Float(*x)).collect()),
        }
    }
}

impl Scale {
    pub fn factors(self) -> [f64; 3] {
        match self {
            Scale::Uniform(x) => [x; 3],
            Scale::PerAxis(v) => v,
        }
    }
}

// ---- Locations ----

/// `file:line:column` (1-based, column in characters) of a byte offset in `text`.
pub fn location(path: &Path, text: &str, span: Option<Range<usize>>) -> String {
    let Some(span) = span else { return path.display().to_string() };
    let start = floor_char_boundary(text, span.start.min(text.len()));
    let before = &text[..start];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    format!("{}:{line}:{column}", path.display())
}

fn floor_char_boundary(text: &str, mut i: usize) -> usize {
    while !text.is_char_boundary(i) {
        i -= 1;
    }
    i
}

// ---- Reading ----

/// Parses and checks a scene file's text (no other file is read).
pub fn parse(path: &Path, text: &str) -> Result<SceneFile> {
    toml::from_str(text).map_err(|e| anyhow!("{}: {}", location(path, text, e.span()), e.message().trim_end()))
}

/// A scene file turned into a scene, still in world coordinates.
pub struct Resolved {
    pub scene: WorldScene,
    pub settings: SceneSettings,
    pub warnings: Vec<String>,
}

/// Reads a scene file and every mesh it names.
pub fn load(path: &Path, files: &dyn Files) -> Result<Resolved> {
    let bytes = files.read(path).map_err(|e| anyhow!("{}: cannot read: {e}", path.display()))?;
    let text = std::str::from_utf8(crate::files::without_bom(&bytes))
        .map_err(|e| anyhow!("{}: not UTF-8 text (byte {})", path.display(), e.valid_up_to()))?;
    let file = parse(path, text)?;
    resolve(path, text, &file, files)
}

/// The render settings a scene file states (unset items stay unset).
pub fn settings_of(file: &SceneFile) -> SceneSettings {
    let (c, r) = (&file.camera, &file.render);
    let f32x3 = |v: [f64; 3]| [v[0] as f32, v[1] as f32, v[2] as f32];
    SceneSettings {
        width: c.width.map(|s| s.0),
        height: c.height.map(|s| s.0),
        spp: r.spp.map(|s| s.0),
        bounces: r.bounces.map(|b| b.0),
        seed: r.seed,
        sampler: r.sampler,
        connect: r.connect,
        time_limit_s: r.time_limit.map(|t| t.0),
        eye: c.eye.map(|p| p.0),
        target: c.target.map(|p| p.0),
        up: c.up.map(|p| p.0),
        fov_deg: c.fov.map(|f| f.0 as f32),
        environment: file.environment.as_ref().and_then(|e| match e.get_ref() {
            Environment::Color(c) => Some(f32x3(c.0)),
            Environment::Map(_) => None,
        }),
    }
}

/// The mesh's placement.
pub fn placement(m: &MeshSection) -> Placement {
    Placement {
        scale: m.scale.map_or(DVec3::ONE, |s| DVec3::from(s.factors())),
        rotate_deg: m.rotate.map_or(DVec3::ZERO, Point::dvec3),
        translate: m.translate.map_or(DVec3::ZERO, Point::dvec3),
    }
}

/// Loads the meshes of a parsed scene file (paths relative to `path`'s folder) and assembles
/// the scene: scene materials first (in name order), then each mesh's MTL materials.
pub fn resolve(path: &Path, text: &str, file: &SceneFile, files: &dyn Files) -> Result<Resolved> {
    let at = |span: Range<usize>| location(path, text, Some(span));
    if file.meshes.is_empty() {
        bail!("{}: no [[mesh]] entries: a scene needs at least one mesh", path.display());
    }
    let dir = path.parent().unwrap_or(Path::new(""));
    let mut materials = Vec::new();
    let mut names = Vec::new();
    let mut index_of = BTreeMap::new();
    let mut textures = TextureSet::default();
    for (name, m) in &file.materials {
        index_of.insert(name.as_str(), materials.len() as u32);
        let mut material = scene_material(m);
        let texture = [("albedo_texture", &m.albedo_texture), ("base_color_texture", &m.base_color_texture)]
            .into_iter()
            .find_map(|(key, t)| t.as_ref().map(|t| (key, t)));
        if let Some((key, t)) = texture {
            let wanted_by = format!("{}: material {name:?}: {key} {:?}", at(t.span()), t.get_ref());
            material.textures[TEXTURE_ALBEDO] =
                textures.load(files, &dir.join(t.get_ref()), Kind::Colour, &wanted_by)?;
        }
        materials.push(material);
        names.push(name.clone());
    }
    let lookup = |name: &Spanned<String>| -> Result<u32> {
        index_of.get(name.get_ref().as_str()).copied().ok_or_else(|| {
            let known: Vec<&str> = index_of.keys().copied().collect();
            anyhow!(
                "{}: no material named {:?} in [materials] (defined: {})",
                at(name.span()),
                name.get_ref(),
                if known.is_empty() { "none".into() } else { known.join(", ") }
            )
        })
    };
    let mut triangles = Vec::new();
    let mut material_of = Vec::new();
    let mut attributes: Vec<WorldAttributes> = Vec::new();
    let mut warnings = Vec::new();
    let mut punctual_lights = Vec::new();
    for m in &file.meshes {
        let mesh_path = dir.join(m.file.get_ref());
        let mesh = crate::scene::gltf_file::load_any_mesh(&mesh_path, files)
            .with_context(|| format!("{}: mesh {:?}", at(m.file.span()), m.file.get_ref()))?;
        let whole = m.material.as_ref().map(&lookup).transpose()?;
        let mut by_name = BTreeMap::new();
        for (mtl_name, target) in &m.materials {
            if !mesh.scene.material_names.iter().any(|n| n == mtl_name) {
                bail!(
                    "{}: mesh {:?} has no MTL material named {mtl_name:?} (it has: {})",
                    at(target.span()),
                    m.file.get_ref(),
                    mesh.scene.material_names.join(", ")
                );
            }
            by_name.insert(mtl_name.as_str(), lookup(target)?);
        }
        // The global index of each of this mesh's local materials.
        let mut global = Vec::with_capacity(mesh.scene.materials.len());
        // The mesh's textures join the scene's; its materials' slots move with them.
        let shift = textures.append(mesh.scene.textures);
        for (local, name) in mesh.scene.material_names.iter().enumerate() {
            let g = match by_name.get(name.as_str()).copied().or(whole) {
                Some(g) => g,
                None => {
                    let mut material = mesh.scene.materials[local];
                    for slot in material.textures.iter_mut().filter(|t| **t != NO_TEXTURE) {
                        *slot += shift;
                    }
                    materials.push(material);
                    names.push(name.clone());
                    materials.len() as u32 - 1
                }
            };
            global.push(g);
        }
        let mut placed = mesh.scene.triangles;
        placement(m).apply(&mut placed);
        let mut placed_attributes = mesh.scene.attributes;
        placement(m).apply_attributes(&mut placed_attributes);
        // One entry per triangle once any mesh has attributes (defaults for those without).
        if !placed_attributes.is_empty() || !attributes.is_empty() {
            attributes.resize(triangles.len(), WorldAttributes::default());
            placed_attributes.resize(placed.len(), WorldAttributes::default());
            attributes.extend(placed_attributes);
        }
        for v in placed.iter().flatten() {
            if !v.is_finite() || v.abs().max_element() > MAX_COORDINATE as f64 {
                bail!(
                    "{}: mesh {:?}: placed vertex {v} is not finite or beyond ±{MAX_COORDINATE:e}",
                    at(m.file.span()),
                    m.file.get_ref(),
                );
            }
        }
        triangles.extend(placed);
        material_of.extend(mesh.scene.material_of.iter().map(|&l| global[l as usize]));
        // A glTF file's lights move with its mesh.
        let m4 = placement(m).matrix();
        let linear = DMat3::from_mat4(m4);
        punctual_lights.extend(mesh.scene.punctual_lights.iter().map(|l| PunctualLight {
            position: m4.transform_point3(l.position),
            direction: linear * l.direction,
            ..*l
        }));
        warnings.extend(mesh.warnings);
    }
    if !attributes.is_empty() {
        attributes.resize(triangles.len(), WorldAttributes::default());
    }
    let mut environment_map = None;
    if let Some(e) = &file.environment {
        if let Environment::Map(m) = e.get_ref() {
            let map_path = dir.join(&m.file);
            let strength = m.strength.unwrap_or(1.0);
            if !(strength.is_finite() && (0.0..=f32::MAX as f64).contains(&strength)) {
                bail!("{}: environment map strength {strength} must be finite and non-negative", at(e.span()));
            }
            let rotate = m.rotate.map_or([0.0; 3], |r| r.0);
            environment_map = Some(
                crate::scene::EnvironmentMap::read(&map_path, strength as f32, rotate)
                    .with_context(|| format!("{}: environment map {:?}", at(e.span()), m.file))?,
            );
        }
    }
    for l in &file.lights {
        punctual_lights.push(l.get_ref().light().map_err(|err| anyhow!("{}: [[light]]: {err}", at(l.span())))?);
    }
    let scene = WorldScene {
        triangles,
        material_of,
        materials,
        material_names: names,
        attributes,
        textures,
        environment_map,
        punctual_lights,
    };
    Ok(Resolved { scene, settings: settings_of(file), warnings })
}

// ---- Writing ----

/// `to` expressed relative to the folder `from` (both absolute).
fn relative_path(to: &Path, from: &Path) -> PathBuf {
    let (t, f): (Vec<Component>, Vec<Component>) = (to.components().collect(), from.components().collect());
    let common = t.iter().zip(&f).take_while(|(a, b)| a == b).count();
    // Sharing only the root (or a drive) is no relation worth a chain of `..`.
    if common <= 1 {
        return to.to_path_buf();
    }
    let mut out = PathBuf::new();
    for _ in common..f.len() {
        out.push("..");
    }
    for c in &t[common..] {
        out.push(c.as_os_str());
    }
    out
}

/// Rewrites each mesh and texture path (relative to `scene_path`'s folder) to be relative to
/// `out_path`'s.
pub fn rebase_meshes(file: &mut SceneFile, scene_path: &Path, out_path: &Path) -> Result<()> {
    let out_dir = absolute_dir(out_path)?;
    let scene_dir = absolute_dir(scene_path)?;
    let rebase = |file: &str| -> Result<String> {
        let abs = scene_dir.join(file);
        let abs = abs.canonicalize().unwrap_or(abs);
        let rel = relative_path(&abs, &out_dir);
        Ok(rel.to_str().ok_or_else(|| anyhow!("{}: path is not UTF-8", rel.display()))?.to_string())
    };
    for m in &mut file.meshes {
        m.file = Spanned::new(0..0, rebase(m.file.get_ref())?);
    }
    for m in file.materials.values_mut() {
        for t in [&mut m.albedo_texture, &mut m.base_color_texture].into_iter().flatten() {
            *t = Spanned::new(0..0, rebase(t.get_ref())?);
        }
    }
    if let Some(e) = &mut file.environment {
        if let Environment::Map(m) = e.get_mut() {
            m.file = rebase(&m.file)?;
        }
    }
    Ok(())
}

fn absolute_dir(file: &Path) -> Result<PathBuf> {
    let dir = match file.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    dir.canonicalize().map_err(|e| anyhow!("{}: {e}", dir.display()))
}

/// The shortest decimal that reads back as exactly `x` (0.278 rather than 0.27799999713897705),
/// as the f64 a TOML file holds: written out, read and rounded to f32 it gives `x` again.
pub fn tidy(x: f32) -> f64 {
    let short: f64 = format!("{x}").parse().unwrap_or(x as f64);
    if short as f32 == x {
        short
    } else {
        x as f64
    }
}

/// A scene file stating `settings` in full and placing the meshes as given.
pub fn with_settings(mut file: SceneFile, s: &SceneSettings) -> Result<SceneFile> {
    let point = |v: Option<[f64; 3]>| v.map(Point);
    let side = |v: Option<u32>| v.map(|v| Side::try_from(v as i64)).transpose();
    file.camera = CameraSection {
        eye: point(s.eye),
        target: point(s.target),
        up: point(s.up),
        fov: s.fov_deg.map(|f| Fov::try_from(tidy(f))).transpose().map_err(|e| anyhow!(e))?,
        width: side(s.width).map_err(|e| anyhow!(e))?,
        height: side(s.height).map_err(|e| anyhow!(e))?,
    };
    file.render = RenderSection {
        spp: s.spp.map(|v| Spp::try_from(v as i64)).transpose().map_err(|e| anyhow!(e))?,
        bounces: s.bounces.map(|v| Bounces::try_from(v as i64)).transpose().map_err(|e| anyhow!(e))?,
        seed: s.seed,
        sampler: s.sampler,
        connect: s.connect,
        time_limit: s.time_limit_s.map(Seconds::try_from).transpose().map_err(|e| anyhow!(e))?,
    };
    // A map stays as the file gives it; a colour is stated in full.
    if !matches!(file.environment.as_ref().map(|e| e.get_ref()), Some(Environment::Map(_))) {
        file.environment = s
            .environment
            .map(|v| Color::try_from(vec![tidy(v[0]), tidy(v[1]), tidy(v[2])]))
            .transpose()
            .map_err(|e| anyhow!(e))?
            .map(|c| Spanned::new(0..0, Environment::Color(c)));
    }
    Ok(file)
}

/// A scene file naming one OBJ by its file name (what `export` writes for an OBJ scene, before
/// [`rebase_meshes`] makes the path relative to the output).
pub fn for_obj(obj: &Path) -> SceneFile {
    let name = obj.file_name().map_or_else(|| obj.to_string_lossy().into_owned(), |n| n.to_string_lossy().into_owned());
    SceneFile {
        meshes: vec![MeshSection {
            file: Spanned::new(0..0, name),
            scale: None,
            rotate: None,
            translate: None,
            material: None,
            materials: BTreeMap::new(),
        }],
        ..Default::default()
    }
}

/// The TOML text of a scene file.
pub fn to_toml(file: &SceneFile, comment: &str) -> Result<String> {
    let body = toml::to_string(file).map_err(|e| anyhow!("writing the scene as TOML: {e}"))?;
    let mut text = String::new();
    for line in comment.lines() {
        text.push_str("# ");
        text.push_str(line);
        text.push('\n');
    }
    text.push('\n');
    text.push_str(&body);
    Ok(text)
}
