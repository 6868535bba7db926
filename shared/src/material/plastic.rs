//! Plastic: a Lambertian base under a smooth dielectric coating, as Mitsuba 3's `plastic` with
//! `ext_ior = 1` and `nonlinear = false` (after Weidlich & Wilkie 2007, "Arbitrarily Layered
//! Micro-Facet Surfaces"): the coating reflects the Fresnel fraction F(θ) specularly; light that
//! enters is scattered by the base, loses the fraction the coating's inside reflects back (the
//! diffuse Fresnel reflectance F_dr, summed as a geometric series), and leaves through the
//! coating again, with 1/η² for the change of solid angle:
//! f = ρ / (1 − F_dr) · (1 − F(θ_o))(1 − F(θ_i)) / (π η²).
//! `albedo` is ρ, `params.y` the coating's index of refraction.
//!
//! With `params.x` = α > 0 the coating is rough, as Mitsuba 3's `roughplastic` (GGX, visible
//! normals, `nonlinear = false`): its specular lobe is a GGX microfacet reflection
//! F·D·G/(4 cos θ_o cos θ_i); the base's lobe uses the rough interface's directional transmittance t(μ)
//! (tabulated by the host, `rough_plastic_transmittance`) in place of 1 − F, and its internal
//! reflectance in place of F_dr: f = ρ/(1 − R_int) · t(cos θ_o) t(cos θ_i) / (π η²); the lobes
//! are picked with the weight 1 − t(cos θ_o) in place of F.
use super::dielectric::fresnel_dielectric;
use super::microfacet::{ggx_d, ggx_g1, ggx_sample_visible_at};
use super::{BsdfSample, DELTA_PDF};
use crate::glam::Vec3;
use crate::layout::Material;
use crate::sampling::{cosine_hemisphere_at, INV_PI};
use crate::vecmath::{dot, normalize, xyz};

/// Points of the rough coating's transmittance table over μ = cos θ in [0, 1] (Mitsuba's
/// `MI_ROUGH_TRANSMITTANCE_RES`).
pub const ROUGH_PLASTIC_TABLE_RES: u32 = 64;
/// Words of one table in the texture buffer: per interval k, the value at its start and the
/// step to the next point (`rough_plastic_transmittance`), the last pair (t(1), 0).
pub const ROUGH_PLASTIC_TABLE_WORDS: u32 = 2 * ROUGH_PLASTIC_TABLE_RES;

/// The rough coating's transmittance t(μ) from the table at word `table` of `words`, linearly
/// interpolated between the 64 points μ_k = k/63 as Mitsuba's `lerp_gather`. The table holds
/// each interval's start value and step, so the interpolation is v + d·f (the shader compiler
/// would turn v0 + (v1 − v0)·f into its own interpolation, which rounds differently).
#[inline]
pub fn rough_plastic_transmittance(words: &[u32], table: u32, mu: f32) -> f32 {
    let x = mu * (ROUGH_PLASTIC_TABLE_RES - 1) as f32;
    let k = (x as u32).min(ROUGH_PLASTIC_TABLE_RES - 2);
    let at = (table + 2 * k) as usize;
    let v = f32::from_bits(words[at]);
    let d = f32::from_bits(words[at + 1]);
    v + d * (x - k as f32)
}

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

/// The rough coating's pick of the specular lobe and the base's, for t_o = t(cos θ_o): with
/// F = 1 − t_o as for the smooth coating.
#[inline]
fn rough_lobes(m: &Material, t_o: f32) -> (f32, f32) {
    let w = coating_share(m);
    let f_o = 1.0 - t_o;
    let sum = lobe_sum(f_o, w);
    (f_o * w / sum, t_o * (1.0 - w) / sum)
}

/// The rough coating's BSDF value and the pdf of `sample_rough` in the local frame.
#[inline]
fn eval_rough(m: &Material, words: &[u32], o: Vec3, i: Vec3) -> (Vec3, f32) {
    let (alpha, eta) = (m.params.x, m.params.y);
    let h = normalize(o + i);
    let d = ggx_d(alpha, h);
    let g1_o = ggx_g1(alpha, o, h);
    let fresnel = fresnel_dielectric(dot(o, h), eta).0;
    // Mitsuba's value F·D·G/(4 cos θ_o) holds the cosine of θ_i; f is without it (4·x is exact,
    // so the compiler's order of the products does not matter).
    let specular = fresnel * d * (g1_o * ggx_g1(alpha, i, h)) / ((4.0 * o.z) * i.z);
    let t_o = rough_plastic_transmittance(words, m.table, o.z);
    let t_i = rough_plastic_transmittance(words, m.table, i.z);
    let value = xyz(m.albedo) * (m.params.z * (t_o * t_i)) + Vec3::splat(specular);
    let (p_specular, p_diffuse) = rough_lobes(m, t_o);
    let pdf = p_specular * (g1_o * d / (4.0 * o.z)) + p_diffuse * (i.z * INV_PI);
    (value, pdf)
}

/// The rough coating's sample: a GGX visible normal's mirror direction or the base's cosine
/// lobe, picked with `u3`; the weight is f·cos/pdf of the mixture.
#[inline]
fn sample_rough(m: &Material, words: &[u32], o: Vec3, disk: (f32, f32), u3: f32) -> BsdfSample {
    let alpha = m.params.x;
    let t_o = rough_plastic_transmittance(words, m.table, o.z);
    let (p_specular, _) = rough_lobes(m, t_o);
    let i = if u3 < p_specular {
        let h = ggx_sample_visible_at(alpha, o, disk);
        h * (2.0 * dot(o, h)) - o
    } else {
        cosine_hemisphere_at(disk)
    };
    if i.z <= 0.0 {
        return BsdfSample::NONE;
    }
    let (value, pdf) = eval_rough(m, words, o, i);
    if pdf <= 0.0 {
        return BsdfSample::NONE;
    }
    BsdfSample { wi: i, weight: value * (i.z / pdf), pdf }
}

/// `words`: the texture buffer, which holds a rough coating's table.
#[inline]
pub fn eval(m: &Material, words: &[u32], o: Vec3, i: Vec3) -> (Vec3, f32) {
    let eta = m.params.y;
    if (o.z <= 0.0) | (i.z <= 0.0) {
        return (Vec3::ZERO, 0.0);
    }
    if m.params.x > 0.0 {
        return eval_rough(m, words, o, i);
    }
    let f_o = fresnel_dielectric(o.z, eta).0;
    let w = coating_share(m);
    let p_diffuse = (1.0 - f_o) * (1.0 - w) / lobe_sum(f_o, w);
    let f_i = fresnel_dielectric(i.z, eta).0;
    (diffuse_value(m, f_o, f_i), p_diffuse * (i.z * INV_PI))
}

/// The coating's mirror reflection (or, rough, a GGX reflection) or the base's cosine lobe,
/// picked with `u3`.
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn sample(m: &Material, words: &[u32], o: Vec3, disk: (f32, f32), u3: f32) -> BsdfSample {
    let eta = m.params.y;
    if o.z <= 0.0 {
        return BsdfSample::NONE;
    }
    if m.params.x > 0.0 {
        return sample_rough(m, words, o, disk, u3);
    }
    let f_o = fresnel_dielectric(o.z, eta).0;
    let w = coating_share(m);
    let sum = lobe_sum(f_o, w);
    if u3 < f_o * w / sum {
        // F / p_specular = sum / w.
        let i = Vec3::new(-o.x, -o.y, o.z);
        return BsdfSample { wi: i, weight: Vec3::splat(sum / w), pdf: DELTA_PDF };
    }
    let i = cosine_hemisphere_at(disk);
    let p_diffuse = (1.0 - f_o) * (1.0 - w) / sum;
    let pdf = p_diffuse * (i.z * INV_PI);
    if pdf <= 0.0 {
        return BsdfSample::NONE;
    }
    // f·cos/pdf = (f·π) / p_diffuse = ρ·(1 − F_i)·scale·sum / (1 − w).
    let f_i = fresnel_dielectric(i.z, eta).0;
    let weight = xyz(m.albedo) * ((1.0 - f_i) * m.params.w * (sum / (1.0 - w)));
    BsdfSample { wi: i, weight, pdf }
}
