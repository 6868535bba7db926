//! The in-memory scene: world-space triangles, their materials, and the light table.
use anyhow::{bail, Result};
use shared::glam::{Vec3, Vec4};
use shared::layout::{Light, Material, Triangle, TriangleInfo, MATERIAL_DIFFUSE, NO_LIGHT};
use shared::material::is_emissive;
use shared::triangle::geometric_normal;
use shared::vecmath::{length, luminance, xyz};

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
}

pub fn diffuse(albedo: Vec3, emission: Vec3) -> Material {
    Material {
        kind: MATERIAL_DIFFUSE,
        _pad: [0; 3],
        albedo: albedo.extend(0.0),
        emission: emission.extend(0.0),
        params: Vec4::ZERO,
    }
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
        if triangles.len() != material_of.len() {
            bail!("{} triangles but {} material indices", triangles.len(), material_of.len());
        }
        if triangles.len() >= (1 << 30) {
            bail!("{} triangles: at most 2^30 are supported", triangles.len());
        }
        let mut kept = Vec::with_capacity(triangles.len());
        let mut info = Vec::with_capacity(triangles.len());
        let mut dropped = 0;
        for (t, &m) in triangles.iter().zip(&material_of) {
            if m as usize >= materials.len() {
                bail!("material index {m} out of range ({} materials)", materials.len());
            }
            for v in [t.v0, t.v1, t.v2] {
                if !v.is_finite() {
                    bail!("non-finite vertex {v:?}");
                }
            }
            if length(geometric_normal(t)) == 0.0 {
                dropped += 1;
                continue;
            }
            kept.push(*t);
            info.push(TriangleInfo { material: m, light: NO_LIGHT });
        }
        let mut lights = Vec::new();
        let mut total = 0.0f64;
        for (i, t) in kept.iter().enumerate() {
            let m = &materials[info[i].material as usize];
            if is_emissive(m) {
                let area = 0.5 * length(geometric_normal(t));
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
        Ok(Self {
            triangles: kept,
            info,
            materials,
            material_names,
            lights,
            bounds_min: lo,
            bounds_max: hi,
            dropped_degenerate: dropped,
        })
    }
}
