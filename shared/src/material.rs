//! Materials: Lambertian reflection and one-sided area emission, dispatched on `Material::kind`
//! unless the variant has one material kind only (`features::Variant::only_material`).
use crate::features::{Variant, FEATURE_DIFFUSE};
use crate::glam::Vec3;
use crate::layout::{Material, MATERIAL_DIFFUSE};
use crate::sampling::{cosine_hemisphere, orthonormal_basis, INV_PI};
use crate::vecmath::{dot, xyz};

/// A direction sampled from a BSDF with its weight f·cos/pdf and its solid-angle pdf.
#[derive(Clone, Copy)]
pub struct BsdfSample {
    pub wi: Vec3,
    pub weight: Vec3,
    pub pdf: f32,
}

/// BSDF value f(wi) for a surface with shading normal `n` facing the incoming ray. Diffuse is
/// two-sided (`n` is already flipped toward the viewer), as in Cycles.
#[inline]
pub fn eval(v: Variant, m: &Material, n: Vec3, wi: Vec3) -> (Vec3, f32) {
    if v.only_material(FEATURE_DIFFUSE) | (m.kind == MATERIAL_DIFFUSE) {
        let c = dot(n, wi);
        if c <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        return (xyz(m.albedo) * INV_PI, c * INV_PI);
    }
    (Vec3::ZERO, 0.0)
}

/// Samples wi ∝ the BSDF's cosine lobe.
#[inline]
pub fn sample(v: Variant, m: &Material, n: Vec3, u1: f32, u2: f32) -> BsdfSample {
    let local = cosine_hemisphere(u1, u2);
    let (t, b) = orthonormal_basis(n);
    let wi = t * local.x + b * local.y + n * local.z;
    if v.only_material(FEATURE_DIFFUSE) | (m.kind == MATERIAL_DIFFUSE) {
        // f·cos/pdf = (ρ/π)·cos / (cos/π) = ρ.
        return BsdfSample { wi, weight: xyz(m.albedo), pdf: local.z * INV_PI };
    }
    BsdfSample { wi, weight: Vec3::ZERO, pdf: 0.0 }
}

/// Radiance leaving an emitter toward direction `-d` (d: the arriving ray's direction):
/// emission is one-sided, from the counter-clockwise side (`normal` is the geometric one).
#[inline]
pub fn emitted(m: &Material, geometric_normal: Vec3, d: Vec3) -> Vec3 {
    if dot(geometric_normal, d) < 0.0 {
        xyz(m.emission)
    } else {
        Vec3::ZERO
    }
}

#[inline]
pub fn is_emissive(m: &Material) -> bool {
    (m.emission.x > 0.0) | (m.emission.y > 0.0) | (m.emission.z > 0.0)
}
