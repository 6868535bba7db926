//! Lambertian reflection, two-sided (`n` already faces the viewer), as in Cycles.
use super::BsdfSample;
use crate::glam::Vec3;
use crate::layout::Material;
use crate::sampling::{cosine_hemisphere, orthonormal_basis, INV_PI};
use crate::vecmath::{dot, xyz};

#[inline]
pub fn eval(m: &Material, n: Vec3, wi: Vec3) -> (Vec3, f32) {
    let c = dot(n, wi);
    if c <= 0.0 {
        return (Vec3::ZERO, 0.0);
    }
    (xyz(m.albedo) * INV_PI, c * INV_PI)
}

/// wi ∝ the cosine lobe; f·cos/pdf = (ρ/π)·cos / (cos/π) = ρ. Always inlined: the integrator's
/// AVX-512 copies (host `render::cpu`) compile only what is inlined into them for AVX-512.
#[inline(always)]
pub fn sample(m: &Material, n: Vec3, u1: f32, u2: f32) -> BsdfSample {
    let local = cosine_hemisphere(u1, u2);
    let (t, b) = orthonormal_basis(n);
    let wi = t * local.x + b * local.y + n * local.z;
    BsdfSample { wi, weight: xyz(m.albedo), pdf: local.z * INV_PI }
}
