//! The glTF 2.0 metallic-roughness model (glTF 2.0 specification, Appendix B, with
//! KHR_materials_transmission and KHR_materials_ior): a mix by `metallic` of
//! - a metal: GGX specular reflection (Smith G1·G1, visible-normal sampling) tinted by Schlick's
//!   Fresnel with the base colour as f0, and
//! - a dielectric: the same specular lobe weighted by the Fresnel reflectance of index `ior`,
//!   over a base that light enters with the rest: Lambertian reflection of the base colour, or
//!   with probability `transmission` a rough refraction (Walter et al. 2007) tinted by it.
//!
//! Departures from the specification's sketch, for energy conservation: the dielectric's
//! Fresnel is the exact one (`fresnel_dielectric`, of which the specification's Schlick is an
//! approximation; it keeps total internal reflection inside a transmissive object), and the base
//! is weighted by 1 − F at the outgoing direction, not at each half vector (which lets a
//! grazing view reflect almost twice the light it receives). Roughness is perceptual: α =
//! roughness², at least `PRINCIPLED_MIN_ALPHA`, so the model has no delta lobe.
//!
//! Layout: `albedo` base colour; `params` = (α, ior, metallic, transmission); `k.xyz` the
//! absorption coefficient of the medium inside (KHR_materials_volume, applied by the
//! integrator to the distance a ray travels inside); `eta.w` a normal map's scale.
use super::dielectric::{fresnel_dielectric, refract, relative_eta, rough_transmission};
use super::microfacet::{ggx_d, ggx_g1, ggx_sample_visible, ggx_visible_pdf};
use super::{BsdfSample, Frame};
use crate::glam::Vec3;
use crate::layout::Material;
use crate::sampling::{cosine_hemisphere, INV_PI};
use crate::vecmath::{dot, luminance, normalize, xyz};
#[allow(unused_imports)]
use spirv_std::num_traits::Float;

/// The smallest GGX α the model uses (roughness 0.0316): below it the lobe is a mirror in all
/// but name, and its density overflows what light sampling can use.
pub const PRINCIPLED_MIN_ALPHA: f32 = 1e-3;

/// Schlick's Fresnel with f0 per channel: f0 + (1 − f0)(1 − c)⁵.
#[inline]
fn schlick(f0: Vec3, c: f32) -> Vec3 {
    let x = (1.0 - c).clamp(0.0, 1.0);
    let x2 = x * x;
    let x5 = x2 * x2 * x;
    f0 + (Vec3::ONE - f0) * x5
}

/// The lobes' selection probabilities (specular, diffuse, transmission) for outgoing local
/// direction `o`: each lobe's weight at o.
#[inline]
fn lobe_probabilities(m: &Material, o: Vec3, eta: f32) -> (f32, f32, f32) {
    let base = xyz(m.albedo);
    let (metallic, transmission) = (m.params.z, m.params.w);
    let f_n = fresnel_dielectric(o.z, eta).0;
    let dielectric = 1.0 - metallic;
    let specular = metallic * luminance(schlick(base, o.z)) + dielectric * f_n;
    let entering = dielectric * (1.0 - f_n) * luminance(base);
    let (diffuse, through) = (entering * (1.0 - transmission), entering * transmission);
    // Diffuse and transmission share what enters: their sum is `entering` (added apart, Mesa
    // regroups the three terms and rounds differently from the CPU).
    let sum = specular + entering;
    if sum <= 0.0 {
        return (0.0, 0.0, 0.0);
    }
    (specular / sum, diffuse / sum, through / sum)
}

#[inline]
fn alpha(m: &Material) -> f32 {
    m.params.x.max(PRINCIPLED_MIN_ALPHA)
}

/// f (without the cosine) and the pdf of `sample` for local directions; `o.z > 0`.
#[inline]
fn eval_local(m: &Material, o: Vec3, i: Vec3, eta: f32) -> (Vec3, f32) {
    let a = alpha(m);
    let base = xyz(m.albedo);
    let (metallic, transmission) = (m.params.z, m.params.w);
    let (p_spec, p_diff, p_through) = lobe_probabilities(m, o, eta);
    let f_n = fresnel_dielectric(o.z, eta).0;
    let entering = (1.0 - metallic) * (1.0 - f_n);
    if i.z > 0.0 {
        let h = normalize(o + i);
        let oh = dot(o, h);
        let spec = ggx_d(a, h) * ggx_g1(a, o, h) * ggx_g1(a, i, h) / (4.0 * o.z * i.z);
        let tint = schlick(base, oh) * metallic + Vec3::splat((1.0 - metallic) * fresnel_dielectric(oh, eta).0);
        let value = tint * spec + base * (entering * (1.0 - transmission) * INV_PI);
        let pdf = p_spec * ggx_visible_pdf(a, o, h) + p_diff * (i.z * INV_PI);
        return (value, pdf);
    }
    if (i.z == 0.0) | (p_through <= 0.0) {
        return (Vec3::ZERO, 0.0);
    }
    let (value, pdf) = rough_transmission(a, o, i, eta);
    (base * (entering * transmission * value), p_through * pdf)
}

#[inline]
pub fn eval(m: &Material, n: Vec3, wo: Vec3, wi: Vec3, front: bool) -> (Vec3, f32) {
    let f = Frame::new(n);
    let (o, i) = (f.to_local(wo), f.to_local(wi));
    if o.z <= 0.0 {
        return (Vec3::ZERO, 0.0);
    }
    eval_local(m, o, i, relative_eta(m.params.y, front))
}

/// Picks a lobe with `u3`, draws a direction from it
/// with `u1`, `u2`, and weighs it by the whole model: f·|cos| / (the mixture's pdf).
#[inline]
pub fn sample(m: &Material, n: Vec3, wo: Vec3, front: bool, u1: f32, u2: f32, u3: f32) -> BsdfSample {
    let eta = relative_eta(m.params.y, front);
    let f = Frame::new(n);
    let o = f.to_local(wo);
    if o.z <= 0.0 {
        return BsdfSample::NONE;
    }
    let a = alpha(m);
    let (p_spec, p_diff, p_through) = lobe_probabilities(m, o, eta);
    if p_spec + p_diff + p_through <= 0.0 {
        return BsdfSample::NONE;
    }
    let specular = u3 < p_spec;
    let diffuse = !specular & (u3 < p_spec + p_diff);
    let i = if specular {
        let h = ggx_sample_visible(a, o, u1, u2);
        let i = h * (2.0 * dot(o, h)) - o;
        // A reflection below the surface is no direction (`eval` would read it as refracted).
        if i.z <= 0.0 {
            return BsdfSample::NONE;
        }
        i
    } else if diffuse {
        cosine_hemisphere(u1, u2)
    } else {
        let h = ggx_sample_visible(a, o, u1, u2);
        let oh = dot(o, h);
        let (_, cos_t) = fresnel_dielectric(oh, eta);
        if (oh <= 0.0) | (cos_t == 0.0) {
            return BsdfSample::NONE;
        }
        let i = refract(o, h, oh, cos_t, eta);
        if i.z >= 0.0 {
            return BsdfSample::NONE;
        }
        i
    };
    if i.z == 0.0 {
        return BsdfSample::NONE;
    }
    let (value, pdf) = eval_local(m, o, i, eta);
    if pdf <= 0.0 {
        return BsdfSample::NONE;
    }
    BsdfSample { wi: f.to_world(i), weight: value * (i.z.abs() / pdf), pdf }
}
