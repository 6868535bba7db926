//! Smooth dielectrics (glass, water): reflection or refraction chosen by the exact Fresnel
//! reflectance of unpolarised light, radiance scaled by 1/η² across the interface, as Mitsuba 3's
//! `dielectric` with `ext_ior = 1` (the counter-clockwise, front side is outside).
use super::{BsdfSample, Frame, DELTA_PDF};
use crate::glam::Vec3;
use crate::layout::Material;
#[allow(unused_imports)]
use spirv_std::num_traits::Float;

/// Fresnel reflectance at incidence cosine `cos_i` (> 0, on the incident side) for relative index
/// `eta` = η_transmitted / η_incident, with the cosine of the refracted direction (0 under total
/// internal reflection, where the reflectance is 1).
#[inline]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> (f32, f32) {
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return (1.0, 0.0);
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    ((rs * rs + rp * rp) * 0.5, cos_t)
}

/// Reflects with probability F, refracts otherwise; `u` picks. `front`: the ray arrived from
/// outside (the counter-clockwise side), so it enters the medium of index `params.y`.
#[inline]
pub fn sample(m: &Material, n: Vec3, wo: Vec3, front: bool, u: f32) -> BsdfSample {
    let ior = m.params.y;
    let eta = if front { ior } else { 1.0 / ior };
    let f = Frame::new(n);
    let o = f.to_local(wo);
    if o.z <= 0.0 {
        return BsdfSample::NONE;
    }
    let (r, cos_t) = fresnel_dielectric(o.z, eta);
    if u < r {
        let i = Vec3::new(-o.x, -o.y, o.z);
        return BsdfSample { wi: f.to_world(i), weight: Vec3::ONE, pdf: DELTA_PDF };
    }
    // Snell: the tangential part scales by 1/η, the normal part is −cos θ_t.
    let i = Vec3::new(-o.x / eta, -o.y / eta, -cos_t);
    BsdfSample { wi: f.to_world(i), weight: Vec3::splat(1.0 / (eta * eta)), pdf: DELTA_PDF }
}
