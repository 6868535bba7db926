//! Dielectrics (glass, water): reflection or refraction chosen by the exact Fresnel reflectance
//! of unpolarised light, radiance scaled by 1/η² across the interface, as Mitsuba 3's
//! `dielectric` and `roughdielectric` (`distribution = "ggx"`, visible-normal sampling) with
//! `ext_ior = 1`: the counter-clockwise (front) side is outside. A rough interface is Walter et
//! al. 2007 ("Microfacet Models for Refraction through Rough Surfaces", EGSR), sampled by the
//! normals visible from the outgoing direction (Heitz 2018).
use super::microfacet::{ggx_d, ggx_g1, ggx_g1_two_sided, ggx_sample_visible_at, ggx_visible_pdf};
use super::{BsdfSample, DELTA_PDF};
use crate::glam::Vec3;
use crate::layout::Material;
use crate::vecmath::{dot, normalize};
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

/// The relative index across the surface for a ray that arrived on the `front` (outside) side.
#[inline]
pub fn relative_eta(ior: f32, front: bool) -> f32 {
    if front {
        ior
    } else {
        1.0 / ior
    }
}

/// `o` refracted through a surface of normal `h` (o·h = `cos_i` > 0) with relative index `eta`
/// and refracted cosine `cos_t`: the tangential part scales by 1/η, the normal part is −cos θ_t.
#[inline]
pub fn refract(o: Vec3, h: Vec3, cos_i: f32, cos_t: f32, eta: f32) -> Vec3 {
    h * (cos_i / eta - cos_t) - o * (1.0 / eta)
}

/// The half vector of a refraction from `o` to `i` (Walter et al. eq. 16), turned to the
/// upper side; with (o·h + η i·h)², the Jacobian's denominator.
#[inline]
pub fn refraction_half(o: Vec3, i: Vec3, eta: f32) -> (Vec3, f32) {
    let h = normalize(o + i * eta);
    let h = if h.z < 0.0 { -h } else { h };
    let d = dot(o, h) + eta * dot(i, h);
    (h, d * d)
}

/// The Walter et al. transmission term without its Fresnel factor and in radiance units (the
/// 1/η² of radiance and the η² of the Jacobian cancel, as in Mitsuba's radiance mode):
/// D·G·|o·h|·|i·h| / (o_z·|i_z|·(o·h + η i·h)²); and the density of `ggx_sample_visible`'s h,
/// mapped to i: D_o(h)·η²|i·h| / (o·h + η i·h)². Zero when the sides disagree.
#[inline]
pub fn rough_transmission(alpha: f32, o: Vec3, i: Vec3, eta: f32) -> (f32, f32) {
    let (h, denom) = refraction_half(o, i, eta);
    let (oh, ih) = (dot(o, h), dot(i, h));
    let g = ggx_g1(alpha, o, h) * ggx_g1_two_sided(alpha, i, h);
    if (g == 0.0) | (denom == 0.0) {
        return (0.0, 0.0);
    }
    let d = ggx_d(alpha, h);
    let value = d * g * oh * (-ih) / (o.z * (-i.z) * denom);
    let pdf = ggx_g1(alpha, o, h) * oh * d / o.z * (eta * eta * (-ih) / denom);
    (value, pdf)
}

/// BSDF value and pdf of a rough interface (a smooth one has none to evaluate).
#[inline]
pub fn eval(m: &Material, o: Vec3, i: Vec3, front: bool) -> (Vec3, f32) {
    let alpha = m.params.x;
    let eta = relative_eta(m.params.y, front);
    if (alpha == 0.0) | (o.z <= 0.0) | (i.z == 0.0) {
        return (Vec3::ZERO, 0.0);
    }
    if i.z > 0.0 {
        let h = normalize(o + i);
        let fr = fresnel_dielectric(dot(o, h), eta).0;
        let value = fr * ggx_d(alpha, h) * ggx_g1(alpha, o, h) * ggx_g1(alpha, i, h) / (4.0 * o.z * i.z);
        return (Vec3::splat(value), fr * ggx_visible_pdf(alpha, o, h));
    }
    let (h, _) = refraction_half(o, i, eta);
    let oh = dot(o, h);
    if oh <= 0.0 {
        return (Vec3::ZERO, 0.0);
    }
    let t = 1.0 - fresnel_dielectric(oh, eta).0;
    let (value, pdf) = rough_transmission(alpha, o, i, eta);
    (Vec3::splat(t * value), t * pdf)
}

/// Reflects with probability F, refracts otherwise; `u3` picks. A smooth interface picks with
/// `u1` (its direction
/// needs no random numbers); a rough one draws its visible normal from the disk point `disk`.
/// Directions are local to the shading frame (`material::sample`). `front`: the ray arrived from outside (the counter-clockwise side),
/// so it enters the medium of index `params.y`.
#[inline]
pub fn sample(m: &Material, o: Vec3, front: bool, u1: f32, disk: (f32, f32), u3: f32) -> BsdfSample {
    let alpha = m.params.x;
    let eta = relative_eta(m.params.y, front);
    if o.z <= 0.0 {
        return BsdfSample::NONE;
    }
    // The Fresnel term at the normal (smooth) or at a visible normal h (rough): one evaluation
    // for both (a shader inlines it per call).
    let smooth = alpha == 0.0;
    let (mut h, mut oh) = (Vec3::Z, o.z);
    if !smooth {
        h = ggx_sample_visible_at(alpha, o, disk);
        oh = dot(o, h);
        if oh <= 0.0 {
            return BsdfSample::NONE;
        }
    }
    let (r, cos_t) = fresnel_dielectric(oh, eta);
    if smooth {
        if u1 < r {
            let i = Vec3::new(-o.x, -o.y, o.z);
            return BsdfSample { wi: i, weight: Vec3::ONE, pdf: DELTA_PDF };
        }
        let i = Vec3::new(-o.x / eta, -o.y / eta, -cos_t);
        return BsdfSample { wi: i, weight: Vec3::splat(1.0 / (eta * eta)), pdf: DELTA_PDF };
    }
    if u3 < r {
        let i = h * (2.0 * oh) - o;
        if i.z <= 0.0 {
            return BsdfSample::NONE;
        }
        // f·cos/pdf = F·D·G1(o)G1(i)/(4 o_z) ÷ F·G1(o)·D/(4 o_z) = G1(i).
        return BsdfSample { wi: i, weight: Vec3::splat(ggx_g1(alpha, i, h)), pdf: r * ggx_visible_pdf(alpha, o, h) };
    }
    let i = refract(o, h, oh, cos_t, eta);
    if i.z >= 0.0 {
        return BsdfSample::NONE;
    }
    let (value, pdf) = rough_transmission(alpha, o, i, eta);
    if pdf <= 0.0 {
        return BsdfSample::NONE;
    }
    // (1 − F) cancels between the value and the pick; what is left is G1(i)/η² up to the
    // rounding of the half vector recomputed from i.
    BsdfSample { wi: i, weight: Vec3::splat(value * (-i.z) / pdf), pdf: (1.0 - r) * pdf }
}
