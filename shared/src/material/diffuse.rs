//! Lambertian reflection, two-sided (`n` already faces the viewer), as in Cycles.
use super::BsdfSample;
use crate::glam::Vec3;
use crate::layout::Material;
use crate::sampling::{cosine_hemisphere_at, INV_PI};
use crate::vecmath::xyz;

#[inline]
pub fn eval(m: &Material, i: Vec3) -> (Vec3, f32) {
    let c = i.z;
    if c <= 0.0 {
        return (Vec3::ZERO, 0.0);
    }
    (xyz(m.albedo) * INV_PI, c * INV_PI)
}

/// wi ∝ the cosine lobe; f·cos/pdf = (ρ/π)·cos / (cos/π) = ρ. Always inlined: the integrator's
/// AVX-512 copies (host `render::cpu`) compile only what is inlined into them for AVX-512.
#[inline(always)]
pub fn sample(m: &Material, disk: (f32, f32)) -> BsdfSample {
    let i = cosine_hemisphere_at(disk);
    BsdfSample { wi: i, weight: xyz(m.albedo), pdf: i.z * INV_PI }
}
