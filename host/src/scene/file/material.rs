//! A scene file's materials: the `[materials.NAME]` tables, their types and the keys each type
//! takes (checked as the file is read, so an error carries the table's line and column), and the
//! `Material` each one becomes.
use super::{vec3_of, Albedo, Color};
use crate::scene::obj::DEFAULT_ALBEDO;
use crate::scene::{clearcoat, conductor, dielectric, diffuse, plastic, principled, Principled};
use serde::{Deserialize, Serialize};
use shared::glam::Vec3;
use shared::layout::Material;
use shared::material::CONDUCTOR_PRESETS;
use toml::Spanned;

/// A named material. Which keys apply depends on `type`; a key of another type is an error
/// (`TryFrom<RawMaterial>`), reported at the material's table.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(try_from = "RawMaterial")]
pub struct MaterialSection {
    #[serde(rename = "type")]
    pub kind: MaterialKind,
    /// Diffuse or plastic: the base's reflectance, linear RGB in 0..=1 (default 0.5 grey).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub albedo: Option<Albedo>,
    /// Diffuse: a PNG or JPEG (sRGB) that replaces `albedo`, relative to the scene file, looked
    /// up at the mesh's OBJ texture coordinates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub albedo_texture: Option<Spanned<String>>,
    /// Emitted radiance from the front (counter-clockwise) side, linear RGB (default none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub emission: Option<Color>,
    /// Conductor: a named metal (`shared::material::CONDUCTOR_PRESETS`) instead of `eta` and `k`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metal: Option<String>,
    /// Conductor: complex index of refraction, real and imaginary parts per channel.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eta: Option<Color>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k: Option<Color>,
    /// Conductor, dielectric, plastic (its coating): GGX roughness α as Mitsuba's `alpha` (0 or
    /// absent: smooth).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha: Option<Alpha>,
    /// Dielectric, plastic coating, principled: the index of refraction inside (outside 1);
    /// default 1.5.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ior: Option<Ior>,
    /// Principled: base colour, linear RGB in 0..=1 (default 0.8 grey).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_color: Option<Albedo>,
    /// Principled: a PNG or JPEG (sRGB) that replaces `base_color`, as `albedo_texture` does.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_color_texture: Option<Spanned<String>>,
    /// Principled: metallic, 0..=1 (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metallic: Option<Unit>,
    /// Principled: perceptual roughness, 0..=1 (α = roughness²; default 0.5).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub roughness: Option<Unit>,
    /// Principled: the fraction of the dielectric base that refracts, 0..=1 (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transmission: Option<Unit>,
    /// Principled: a clear coat's strength, 0..=1 (default 0: none; KHR_materials_clearcoat).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clearcoat: Option<Unit>,
    /// Principled: the clear coat's perceptual roughness, 0..=1 (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clearcoat_roughness: Option<Unit>,
}

/// A material table as written, before the keys are checked against its type.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawMaterial {
    #[serde(rename = "type", default)]
    kind: MaterialKind,
    albedo: Option<Albedo>,
    albedo_texture: Option<Spanned<String>>,
    emission: Option<Color>,
    metal: Option<String>,
    eta: Option<Color>,
    k: Option<Color>,
    alpha: Option<Alpha>,
    ior: Option<Ior>,
    base_color: Option<Albedo>,
    base_color_texture: Option<Spanned<String>>,
    metallic: Option<Unit>,
    roughness: Option<Unit>,
    transmission: Option<Unit>,
    clearcoat: Option<Unit>,
    clearcoat_roughness: Option<Unit>,
}

impl MaterialKind {
    /// The keys a material of this type takes besides `type` and `emission`.
    pub fn keys(self) -> &'static [&'static str] {
        match self {
            MaterialKind::Diffuse => &["albedo", "albedo_texture"],
            MaterialKind::Conductor => &["metal", "eta", "k", "alpha"],
            MaterialKind::Dielectric => &["ior", "alpha"],
            MaterialKind::Plastic => &["albedo", "albedo_texture", "ior", "alpha"],
            MaterialKind::Principled => &[
                "base_color",
                "base_color_texture",
                "metallic",
                "roughness",
                "transmission",
                "ior",
                "clearcoat",
                "clearcoat_roughness",
            ],
        }
    }
}

impl TryFrom<RawMaterial> for MaterialSection {
    type Error = String;
    fn try_from(r: RawMaterial) -> Result<Self, String> {
        let given = [
            ("albedo", r.albedo.is_some()),
            ("albedo_texture", r.albedo_texture.is_some()),
            ("metal", r.metal.is_some()),
            ("eta", r.eta.is_some()),
            ("k", r.k.is_some()),
            ("alpha", r.alpha.is_some()),
            ("ior", r.ior.is_some()),
            ("base_color", r.base_color.is_some()),
            ("base_color_texture", r.base_color_texture.is_some()),
            ("metallic", r.metallic.is_some()),
            ("roughness", r.roughness.is_some()),
            ("transmission", r.transmission.is_some()),
            ("clearcoat", r.clearcoat.is_some()),
            ("clearcoat_roughness", r.clearcoat_roughness.is_some()),
        ];
        let allowed = r.kind.keys();
        if let Some((key, _)) = given.iter().find(|(key, on)| *on && !allowed.contains(key)) {
            let hint = match *key {
                "alpha" if r.kind == MaterialKind::Principled => {
                    "; a principled material takes roughness (α = roughness²)"
                }
                _ => "",
            };
            return Err(format!(
                "{key} does not apply to a {} material (it takes {} and emission){hint}",
                String::from(r.kind),
                allowed.join(", ")
            ));
        }
        if r.kind == MaterialKind::Conductor {
            match (&r.metal, r.eta.is_some(), r.k.is_some()) {
                (Some(_), false, false) => {}
                (Some(_), _, _) => return Err("give a conductor either metal or eta and k, not both".into()),
                (None, true, true) => {}
                (None, _, _) => {
                    return Err(format!("a conductor needs metal = \"NAME\" ({}) or both eta and k", preset_names()))
                }
            }
            if let Some(name) = &r.metal {
                if preset(name).is_none() {
                    return Err(format!("unknown metal {name:?} (known: {})", preset_names()));
                }
            }
        }
        Ok(Self {
            kind: r.kind,
            albedo: r.albedo,
            albedo_texture: r.albedo_texture,
            emission: r.emission,
            metal: r.metal,
            eta: r.eta,
            k: r.k,
            alpha: r.alpha,
            ior: r.ior,
            base_color: r.base_color,
            base_color_texture: r.base_color_texture,
            metallic: r.metallic,
            roughness: r.roughness,
            transmission: r.transmission,
            clearcoat: r.clearcoat,
            clearcoat_roughness: r.clearcoat_roughness,
        })
    }
}

/// A dielectric's index of refraction when the file gives none (glass).
pub const DEFAULT_IOR: f32 = 1.5;

/// The named metal's (η, κ).
fn preset(name: &str) -> Option<([f32; 3], [f32; 3])> {
    CONDUCTOR_PRESETS.iter().find(|p| p.0 == name).map(|p| (p.1, p.2))
}

fn preset_names() -> String {
    CONDUCTOR_PRESETS.iter().map(|p| p.0).collect::<Vec<_>>().join(", ")
}

/// An index of refraction: finite, within 1e-3..=100.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "f64", into = "f64")]
pub struct Ior(pub f64);

impl TryFrom<f64> for Ior {
    type Error = String;
    fn try_from(v: f64) -> Result<Self, String> {
        if !(1e-3..=100.0).contains(&v) {
            return Err(format!("index of refraction {v} must be within 0.001..=100"));
        }
        Ok(Self(v))
    }
}

impl From<Ior> for f64 {
    fn from(v: Ior) -> f64 {
        v.0
    }
}

/// GGX roughness α within 0..=1.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "f64", into = "f64")]
pub struct Alpha(pub f64);

impl TryFrom<f64> for Alpha {
    type Error = String;
    fn try_from(a: f64) -> Result<Self, String> {
        if !(0.0..=1.0).contains(&a) {
            return Err(format!("roughness alpha {a} must be within 0..=1"));
        }
        Ok(Self(a))
    }
}

impl From<Alpha> for f64 {
    fn from(a: Alpha) -> f64 {
        a.0
    }
}

/// A fraction within 0..=1 (metallic, roughness, transmission).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "f64", into = "f64")]
pub struct Unit(pub f64);

impl TryFrom<f64> for Unit {
    type Error = String;
    fn try_from(v: f64) -> Result<Self, String> {
        if !(0.0..=1.0).contains(&v) {
            return Err(format!("{v} must be within 0..=1"));
        }
        Ok(Self(v))
    }
}

impl From<Unit> for f64 {
    fn from(v: Unit) -> f64 {
        v.0
    }
}

/// Material models (`shared::material`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum MaterialKind {
    #[default]
    Diffuse,
    Conductor,
    Dielectric,
    Plastic,
    Principled,
}

impl TryFrom<String> for MaterialKind {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        match s.as_str() {
            "diffuse" => Ok(MaterialKind::Diffuse),
            "conductor" => Ok(MaterialKind::Conductor),
            "dielectric" => Ok(MaterialKind::Dielectric),
            "plastic" => Ok(MaterialKind::Plastic),
            "principled" => Ok(MaterialKind::Principled),
            "roughconductor" => Err("use type = \"conductor\" with alpha for a rough conductor".into()),
            "roughdielectric" => Err("use type = \"dielectric\" with alpha for a rough dielectric".into()),
            "roughplastic" => Err("use type = \"plastic\" with alpha for a rough plastic coating".into()),
            other => Err(format!(
                "unknown material type {other:?} (expected \"diffuse\", \"conductor\", \"dielectric\", \"plastic\" or \"principled\")"
            )),
        }
    }
}

impl From<MaterialKind> for String {
    fn from(k: MaterialKind) -> String {
        match k {
            MaterialKind::Diffuse => "diffuse".into(),
            MaterialKind::Conductor => "conductor".into(),
            MaterialKind::Dielectric => "dielectric".into(),
            MaterialKind::Plastic => "plastic".into(),
            MaterialKind::Principled => "principled".into(),
        }
    }
}

pub(super) fn scene_material(m: &MaterialSection) -> Material {
    let emission = m.emission.map_or(Vec3::ZERO, |e| vec3_of(e.0));
    match m.kind {
        MaterialKind::Diffuse => diffuse(m.albedo.map_or(Vec3::splat(DEFAULT_ALBEDO), |a| vec3_of(a.0)), emission),
        MaterialKind::Conductor => {
            // The checks of `TryFrom<RawMaterial>` leave a known metal, or both eta and k.
            let (eta, k) = match &m.metal {
                Some(name) => preset(name).map(|(e, k)| (Vec3::from(e), Vec3::from(k))).unwrap_or_default(),
                None => (m.eta.map_or(Vec3::ONE, |e| vec3_of(e.0)), m.k.map_or(Vec3::ZERO, |k| vec3_of(k.0))),
            };
            conductor(eta, k, m.alpha.map_or(0.0, |a| a.0 as f32), emission)
        }
        MaterialKind::Dielectric => {
            dielectric(m.ior.map_or(DEFAULT_IOR, |i| i.0 as f32), m.alpha.map_or(0.0, |a| a.0 as f32), emission)
        }
        MaterialKind::Plastic => plastic(
            m.albedo.map_or(Vec3::splat(DEFAULT_ALBEDO), |a| vec3_of(a.0)),
            m.ior.map_or(DEFAULT_IOR, |i| i.0 as f32),
            m.alpha.map_or(0.0, |a| a.0 as f32),
            emission,
        ),
        MaterialKind::Principled => clearcoat(
            principled(
                &Principled {
                    base_color: m.base_color.map_or(Vec3::splat(0.8), |a| vec3_of(a.0)),
                    metallic: m.metallic.map_or(0.0, |v| v.0 as f32),
                    roughness: m.roughness.map_or(0.5, |v| v.0 as f32),
                    transmission: m.transmission.map_or(0.0, |v| v.0 as f32),
                    ior: m.ior.map_or(DEFAULT_IOR, |i| i.0 as f32),
                },
                emission,
            ),
            m.clearcoat.map_or(0.0, |v| v.0 as f32),
            m.clearcoat_roughness.map_or(0.0, |v| v.0 as f32),
        ),
    }
}
