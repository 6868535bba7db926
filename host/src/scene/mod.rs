//! Scene input: OBJ + MTL (`obj`), TOML scene files (`file`), mesh placement (`transform`), the
//! local frame (`local_frame`), procedural test scenes (`procedural`).
//!
//! This module holds the in-memory scene: triangles in the scene's local frame (f32, as both
//! devices read them), their materials and the light table; and the world-space scene it is made
//! from, kept in f64 until it is placed (`WorldScene`). Vertex attributes (`WorldAttributes`:
//! vertex normals and texture coordinates) and textures (`texture`) travel with the triangles.
pub mod coating;
pub mod environment;
pub mod file;
pub mod gltf_file;
pub mod local_frame;
pub mod obj;
pub mod procedural;
pub mod texture;
pub mod transform;

pub use environment::{EnvironmentMap, PunctualLight};

use anyhow::{bail, Result};
use shared::glam::{DVec3, Vec3, Vec4};
use shared::layout::{
    Light, Material, Triangle, TriangleAttributes, TriangleInfo, ALPHA_CUT, MATERIAL_CONDUCTOR, MATERIAL_DIELECTRIC,
    MATERIAL_DIFFUSE, MATERIAL_PLASTIC, MATERIAL_PRINCIPLED, NO_LIGHT, NO_TEXTURE,
};
use shared::material::is_emissive;
use shared::triangle::area;
use shared::vecmath::{luminance, xyz};

#[derive(Clone, Debug)]
pub struct Scene {
    pub triangles: Vec<Triangle>,
    pub info: Vec<TriangleInfo>,
    pub materials: Vec<Material>,
    pub material_names: Vec<String>,
    pub lights: Vec<Light>,
    pub bounds_min: Vec3,
    pub bounds_max: Vec3,
    /// Zero-area triangles dropped while loading.
    pub dropped_degenerate: usize,
    /// Per triangle its vertex normals and texture coordinates, or empty when no triangle has
    /// any (`shared::layout::TriangleAttributes`).
    pub attributes: Vec<TriangleAttributes>,
    /// The texture buffer (`shared::texture`; empty without textures or rough plastics), then
    /// the rough plastics' coating tables (`coating::append_tables`); and each texture's image
    /// file, in table order.
    pub textures: Vec<u32>,
    pub texture_sources: Vec<String>,
    /// The environment map, if any (`environment`; replaces the constant environment colour).
    pub environment_map: Option<EnvironmentMap>,
    /// Point, spot and directional lights, positions in this scene's local frame.
    pub punctual_lights: Vec<PunctualLight>,
}

/// A triangle in world coordinates, f64 as read and placed.
pub type WorldTriangle = [DVec3; 3];

/// `t` in f64, exactly (the inverse of `round_triangle` for a triangle already in f32).
pub fn widen_triangle(t: &Triangle) -> WorldTriangle {
    [t.v0, t.v1, t.v2].map(|v| xyz(v).as_dvec3())
}

/// `t` rounded to f32 once per coordinate.
pub fn round_triangle(t: &WorldTriangle) -> Triangle {
    let v = |p: DVec3| p.as_vec3().extend(0.0);
    Triangle { v0: v(t[0]), v1: v(t[1]), v2: v(t[2]) }
}

/// A triangle's vertex attributes as read and placed (f64): unit vertex normals (all zero: none,
/// the triangle shades flat) and texture coordinates (u, v) of v0, v1, v2 ((0, 0) where the
/// mesh gives none).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WorldAttributes {
    pub normals: [DVec3; 3],
    pub uv: [[f64; 2]; 3],
}

impl WorldAttributes {
    /// Rounded to f32 in the renderers' layout.
    pub fn round(&self) -> TriangleAttributes {
        let [n0, n1, n2] = self.normals.map(|n| n.as_vec3());
        let [a, b, c] = self.uv.map(|t| [t[0] as f32, t[1] as f32]);
        TriangleAttributes {
            n0: n0.extend(a[0]),
            n1: n1.extend(b[0]),
            n2: n2.extend(c[0]),
            uv_v: Vec4::new(a[1], b[1], c[1], 0.0),
        }
    }
}

/// A scene as read and placed, before it is moved next to the origin and rounded to f32
/// (`into_local`).
#[derive(Clone, Debug, Default)]
pub struct WorldScene {
    pub triangles: Vec<WorldTriangle>,
    /// Per triangle, an index into `materials`.
    pub material_of: Vec<u32>,
    pub materials: Vec<Material>,
    pub material_names: Vec<String>,
    /// Per triangle, or empty when no triangle has vertex normals or texture coordinates.
    pub attributes: Vec<WorldAttributes>,
    /// The images the materials' texture slots name.
    pub textures: texture::TextureSet,
    /// The environment map, if any.
    pub environment_map: Option<EnvironmentMap>,
    /// Point, spot and directional lights, positions in world coordinates (f64).
    pub punctual_lights: Vec<PunctualLight>,
}

impl WorldScene {
    /// The scene in its local frame (`local_frame::place`: moved in f64, each coordinate rounded
    /// to f32 once) and the world position of that frame's origin.
    pub fn into_local(self) -> Result<(Scene, DVec3)> {
        let (triangles, origin) = crate::scene::local_frame::place(&self.triangles);
        let attributes = self.attributes.iter().map(WorldAttributes::round).collect();
        let scene = Scene::with_surfaces(
            triangles,
            self.material_of,
            self.materials,
            self.material_names,
            attributes,
            &self.textures.textures,
        )?;
        let mut scene = scene;
        scene.environment_map = self.environment_map;
        scene.punctual_lights =
            self.punctual_lights.into_iter().map(|l| PunctualLight { position: l.position - origin, ..l }).collect();
        Ok((scene, origin))
    }
}

pub fn diffuse(albedo: Vec3, emission: Vec3) -> Material {
    Material {
        kind: MATERIAL_DIFFUSE,
        table: 0,
        alpha_mode: ALPHA_CUT,
        _pad: 0,
        albedo: albedo.extend(0.0),
        emission: emission.extend(0.0),
        params: Vec4::ZERO,
        eta: Vec4::ZERO,
        k: Vec4::ZERO,
        textures: [NO_TEXTURE; 8],
    }
}

/// A conductor of complex index of refraction `eta` + i·`k`, GGX roughness `alpha` (0: smooth).
pub fn conductor(eta: Vec3, k: Vec3, alpha: f32, emission: Vec3) -> Material {
    Material {
        kind: MATERIAL_CONDUCTOR,
        params: Vec4::new(alpha, 0.0, 0.0, 0.0),
        eta: eta.extend(0.0),
        k: k.extend(0.0),
        ..diffuse(Vec3::ZERO, emission)
    }
}

/// A dielectric of index of refraction `ior` inside (outside 1), GGX roughness `alpha` (0: smooth).
pub fn dielectric(ior: f32, alpha: f32, emission: Vec3) -> Material {
    Material { kind: MATERIAL_DIELECTRIC, params: Vec4::new(alpha, ior, 0.0, 0.0), ..diffuse(Vec3::ZERO, emission) }
}

/// Plastic: a diffuse base of reflectance `albedo` under a coating of index `ior`, smooth
/// (`alpha` = 0) or rough of GGX α `alpha` (Mitsuba's `roughplastic`; `coating`).
pub fn plastic(albedo: Vec3, ior: f32, alpha: f32, emission: Vec3) -> Material {
    let (over_pi, scale) = if alpha > 0.0 {
        coating::CoatingTable::new(alpha, ior).scale(ior)
    } else {
        shared::material::plastic_scale(ior)
    };
    Material { kind: MATERIAL_PLASTIC, params: Vec4::new(alpha, ior, over_pi, scale), ..diffuse(albedo, emission) }
}

/// The parameters of a glTF metallic-roughness material (`shared::material::principled`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Principled {
    pub base_color: Vec3,
    pub metallic: f32,
    /// Perceptual roughness: α = roughness².
    pub roughness: f32,
    pub transmission: f32,
    pub ior: f32,
}

/// A glTF metallic-roughness material.
pub fn principled(p: &Principled, emission: Vec3) -> Material {
    Material {
        kind: MATERIAL_PRINCIPLED,
        params: Vec4::new(p.roughness * p.roughness, p.ior, p.metallic, p.transmission),
        ..diffuse(p.base_color, emission)
    }
}

/// A principled material under a clear coat (KHR_materials_clearcoat): `factor` in [0, 1],
/// perceptual `roughness` (α = roughness²); a factor of 0 leaves it uncoated.
pub fn clearcoat(m: Material, factor: f32, roughness: f32) -> Material {
    let mut m = m;
    m.eta.x = factor;
    m.eta.y = roughness * roughness;
    m
}

impl Scene {
    /// Assembles a scene from triangles with a material index each. Zero-area triangles are
    /// dropped (and counted); emissive triangles become lights picked in proportion to their
    /// power (area × luminance of the emitted radiance).
    pub fn new(
        triangles: Vec<Triangle>,
        material_of: Vec<u32>,
        materials: Vec<Material>,
        material_names: Vec<String>,
    ) -> Result<Self> {
        Self::with_surfaces(triangles, material_of, materials, material_names, Vec::new(), &[])
    }

    /// `new` with vertex attributes (one per triangle, or none) and the textures the materials'
    /// slots name (slot value 1 + index into `textures`).
    pub fn with_surfaces(
        triangles: Vec<Triangle>,
        material_of: Vec<u32>,
        materials: Vec<Material>,
        material_names: Vec<String>,
        attributes: Vec<TriangleAttributes>,
        textures: &[texture::Texture],
    ) -> Result<Self> {
        if triangles.len() != material_of.len() {
            bail!("{} triangles but {} material indices", triangles.len(), material_of.len());
        }
        if !attributes.is_empty() && attributes.len() != triangles.len() {
            bail!("{} triangles but {} vertex attributes", triangles.len(), attributes.len());
        }
        for (i, m) in materials.iter().enumerate() {
            if let Some(&slot) = m.textures.iter().find(|&&t| t as usize > textures.len()) {
                bail!("material {i}: texture {slot} out of range ({} textures)", textures.len());
            }
        }
        if triangles.len() >= (1 << 30) {
            bail!("{} triangles: at most 2^30 are supported", triangles.len());
        }
        let mut kept = Vec::with_capacity(triangles.len());
        let mut info = Vec::with_capacity(triangles.len());
        let mut kept_attributes = Vec::with_capacity(attributes.len());
        let mut dropped = 0;
        for (i, (t, &m)) in triangles.iter().zip(&material_of).enumerate() {
            if m as usize >= materials.len() {
                bail!("material index {m} out of range ({} materials)", materials.len());
            }
            for v in [t.v0, t.v1, t.v2] {
                if !v.is_finite() {
                    bail!("non-finite vertex {v:?}");
                }
            }
            if area(t) == 0.0 {
                dropped += 1;
                continue;
            }
            kept.push(*t);
            info.push(TriangleInfo { material: m, light: NO_LIGHT });
            if let Some(a) = attributes.get(i) {
                kept_attributes.push(*a);
            }
        }
        let mut lights = Vec::new();
        let mut total = 0.0f64;
        for (i, t) in kept.iter().enumerate() {
            let m = &materials[info[i].material as usize];
            if is_emissive(m) {
                let area = area(t);
                let power = area as f64 * luminance(xyz(m.emission)).max(1e-6) as f64;
                info[i].light = lights.len() as u32;
                lights.push(Light { triangle: i as u32, pmf: power as f32, cdf: 0.0, area });
                total += power;
            }
        }
        let mut running = 0.0f64;
        for l in &mut lights {
            let p = l.pmf as f64 / total;
            running += p;
            l.pmf = p as f32;
            l.cdf = running as f32;
        }
        if let Some(last) = lights.last_mut() {
            last.cdf = 1.0;
        }
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for t in &kept {
            for v in [t.v0, t.v1, t.v2] {
                lo = lo.min(xyz(v));
                hi = hi.max(xyz(v));
            }
        }
        if kept.is_empty() {
            lo = Vec3::ZERO;
            hi = Vec3::ZERO;
        }
        let mut scene = Self {
            triangles: kept,
            info,
            materials,
            material_names,
            lights,
            bounds_min: lo,
            bounds_max: hi,
            dropped_degenerate: dropped,
            attributes: kept_attributes,
            textures: if textures.is_empty() { Vec::new() } else { texture::pack(textures)? },
            texture_sources: textures.iter().map(|t| t.source.display().to_string()).collect(),
            environment_map: None,
            punctual_lights: Vec::new(),
        };
        scene.refresh_coating_tables();
        Ok(scene)
    }

    /// Puts the coating tables of the rough plastics among `materials` after the textures in
    /// the texture buffer, replacing any there were (`coating::append_tables`); deterministic,
    /// so a scene read from a .kdc file gets the same tables again. `render::Compiled::new` calls
    /// it, so a material changed after loading gets its table.
    pub fn refresh_coating_tables(&mut self) {
        let kept = texture::packed_len(&self.textures, self.texture_sources.len());
        self.textures.truncate(kept);
        coating::append_tables(&mut self.materials, &mut self.textures);
    }
}
