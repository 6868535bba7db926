//! Plastic: a Lambertian base under a smooth dielectric coating, as Mitsuba 3's `plastic` with
//! `ext_ior = 1` and `nonlinear = false` (after Weidlich & Wilkie 2007, "Arbitrarily Layered
//! Micro-Facet Surfaces"): the coating reflects the Fresnel fraction F(θ) specularly; light that
//! enters is scattered by the base, loses the fraction the coating's inside reflects back (the
//! diffuse Fresnel reflectance F_dr, summed as a geometric series), and leaves through the
//! coating again, with 1/η² for the change of solid angle:
//! f = ρ / (1 − F_dr) · (1 − F(θ_o))(1 − F(θ_i)) / (π η²).
//! `albedo` is ρ, `params.y` the coating's index of refraction.
use super::dielectric::fresnel_dielectric;
use super::{BsdfSample, Frame, DELTA_PDF};
use crate::glam::Vec3;
use crate::layout::Material;
use crate::sampling::{cosine_hemisphere, INV_PI};
use crate::vecmath::xyz;

/// The hemispherical average of the Fresnel reflectance for relative index `eta` (light
/// arriving from the side of index 1), Mitsuba 3's `fresnel_diffuse_reflectance`: Egan and
/// Hilgeman's fit (1973) below 1, d'Eon and Irving's (2011) above.
#[inline]
#[allow(clippy::excessive_precision)] // the published coefficients, as printed
pub fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    let inv = 1.0 / eta;
    if eta < 1.0 {
        0.0636 * inv + (eta * (eta * -1.4399 + 0.7099) + 0.6681)
    } else {
        let p = ((((-1.36881 * inv + 4.98554) * inv - 7.80989) * inv + 6.75335) * inv - 3.4793) * inv;
        p + 0.919317
    }
}

/// The constant factors of the base's lobe for a coating of index `eta`: 1 / (η²(1 − F_dr(1/η)))
/// divided by π (for its value) and as it is (for its sample weight). The host computes them once
/// per material: in the shader, a product with a constant is reassociated differently.
#[inline]
pub fn plastic_scale(eta: f32) -> (f32, f32) {
    let k = 1.0 / (eta * eta * (1.0 - fresnel_diffuse_reflectance(1.0 / eta)));
    (k * INV_PI, k)
}

/// The coating's share w against the base's mean albedo, as Mitsuba weighs the lobes: the
/// coating's lobe is picked with probability F·w / (F·w + (1 − F)(1 − w)).
#[inline]
fn coating_share(m: &Material) -> f32 {
    let rho = xyz(m.albedo);
    1.0 / ((rho.x + rho.y + rho.z) * (1.0 / 3.0) + 1.0)
}

/// F·w + (1 − F)(1 − w), written as (1 − w) + F·(2w − 1): the sum of the two products is the
/// shape of a linear interpolation, which Mesa's compiler replaces by one that rounds differently.
#[inline]
fn lobe_sum(f_o: f32, w: f32) -> f32 {
    (1.0 - w) + f_o * (w + w - 1.0)
}

/// The base's lobe f for Fresnel reflectances `f_o`, `f_i` of the coating at the outgoing and
/// incident directions (`params.z` holds the constant factor with its 1/π).
#[inline]
fn diffuse_value(m: &Material, f_o: f32, f_i: f32) -> Vec3 {
    xyz(m.albedo) * ((1.0 - f_o) * (1.0 - f_i) * m.params.z)
}

#[inline]
pub fn eval(m: &Material, n: Vec3, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
    let eta = m.params.y;
    let f = Frame::new(n);
    let (o, i) = (f.to_local(wo), f.to_local(wi));
    if (o.z <= 0.0) | (i.z <= 0.0) {
        return (Vec3::ZERO, 0.0);
    }
    let f_o = fresnel_dielectric(o.z, eta).0;
    let w = coating_share(m);
    let p_diffuse = (1.0 - f_o) * (1.0 - w) / lobe_sum(f_o, w);
    let f_i = fresnel_dielectric(i.z, eta).0;
    (diffuse_value(m, f_o, f_i), p_diffuse * (i.z * INV_PI))
}

/// The coating's mirror reflection or the base's cosine lobe, picked with `u3`.
#[inline]
pub fn sample(m: &Material, n: Vec3, wo: Vec3, u1: f32, u2: f32, u3: f32) -> BsdfSample {
    let eta = m.params.y;
    let f = Frame::new(n);
    let o = f.to_local(wo);
    if o.z <= 0.0 {
        return BsdfSample::NONE;
    }
    let f_o = fresnel_dielectric(o.z, eta).0;
    let w = coating_share(m);
    let sum = lobe_sum(f_o, w);
    if u3 < f_o * w / sum {
        // F / p_specular = sum / w.
        let i = Vec3::new(-o.x, -o.y, o.z);
        return BsdfSample { wi: f.to_world(i), weight: Vec3::splat(sum / w), pdf: DELTA_PDF };
    }
    let i = cosine_hemisphere(u1, u2);
    let p_diffuse = (1.0 - f_o) * (1.0 - w) / sum;
    let pdf = p_diffuse * (i.z * INV_PI);
    if pdf <= 0.0 {
        return BsdfSample::NONE;
    }
    // f·cos/pdf = (f·π) / p_diffuse = ρ·(1 − F_i)·scale·sum / (1 − w).
    let f_i = fresnel_dielectric(i.z, eta).0;
    let weight = xyz(m.albedo) * ((1.0 - f_i) * m.params.w * (sum / (1.0 - w)));
    BsdfSample { wi: f.to_world(i), weight, pdf }
}
