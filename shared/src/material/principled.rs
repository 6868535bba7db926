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
//! A clear coat (KHR_materials_clearcoat) lies over all of it: a GGX reflection of its own α
//! weighted by `clearcoat` and by the Fresnel reflectance of index 1.5 (the extension's f0 of
//! 0.04, exact rather than Schlick's), over a base that keeps 1 − clearcoat·F of the light, F
//! taken at the outgoing direction as for the base. The coat is thin (no refraction through it)
//! and on the front side only: a ray that meets the surface from inside sees the base alone.
//!
//! Layout: `albedo` base colour; `params` = (α, ior, metallic, transmission); `k.xyz` the
//! absorption coefficient of the medium inside (KHR_materials_volume, applied by the
//! integrator to the distance a ray travels inside); `eta.x` the clear coat's factor and
//! `eta.y` its α (0: no coat); `eta.w` a normal map's scale.
use super::dielectric::{fresnel_dielectric, refract, relative_eta, rough_transmission};
use super::microfacet::{ggx_d, ggx_g1, ggx_sample_visible_at, ggx_visible_pdf};
use super::BsdfSample;
use crate::glam::Vec3;
use crate::layout::Material;
use crate::sampling::{cosine_hemisphere_at, INV_PI};
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

/// The clear coat's index of refraction: KHR_materials_clearcoat's f0 of 0.04.
pub const COAT_IOR: f32 = 1.5;

/// The clear coat a ray meets: its factor and GGX α, or a factor of 0 (none, or a ray from
/// inside).
#[inline]
fn coat(m: &Material, front: bool) -> (f32, f32) {
    let c = if front { m.eta.x } else { 0.0 };
    (c, m.eta.y.max(PRINCIPLED_MIN_ALPHA))
}

/// The lobes' selection probabilities (specular, diffuse, transmission) for outgoing local
/// direction `o`, each lobe's weight at o, and the sum of the weights (0 when the base reflects
/// nothing).
#[inline]
fn lobes(m: &Material, o: Vec3, eta: f32) -> ((f32, f32, f32), f32) {
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
        return ((0.0, 0.0, 0.0), 0.0);
    }
    ((specular / sum, diffuse / sum, through / sum), sum)
}

/// With a coat of factor `c` over a base whose lobes weigh `base_sum` at `o`: the base's share
/// 1 − c·F (F the coat's Fresnel at o) and the probability of sampling the coat, in proportion
/// to c·F against the base's weight times its share.
#[inline]
fn coat_split(c: f32, o: Vec3, base_sum: f32) -> (f32, f32) {
    let w = c * fresnel_dielectric(o.z, COAT_IOR).0;
    let share = 1.0 - w;
    let rest = share * base_sum;
    let total = w + rest;
    let p_coat = if total > 0.0 { w / total } else { 0.0 };
    (share, p_coat)
}

/// The coat's reflection (f without the cosine) and its sampling pdf for `i.z > 0`.
#[inline]
fn coat_local(c: f32, a: f32, o: Vec3, i: Vec3) -> (Vec3, f32) {
    let h = normalize(o + i);
    let oh = dot(o, h);
    let spec = ggx_d(a, h) * ggx_g1(a, o, h) * ggx_g1(a, i, h) / (4.0 * o.z * i.z);
    let f = fresnel_dielectric(oh, COAT_IOR).0;
    (Vec3::splat(c * (f * spec)), ggx_visible_pdf(a, o, h))
}

#[inline]
fn alpha(m: &Material) -> f32 {
    m.params.x.max(PRINCIPLED_MIN_ALPHA)
}

/// f (without the cosine) and the pdf of the base alone for local directions (`o.z > 0`),
/// given the lobes' probabilities at `o` (`lobes`).
#[inline]
fn eval_base(m: &Material, o: Vec3, i: Vec3, eta: f32, probabilities: (f32, f32, f32)) -> (Vec3, f32) {
    let a = alpha(m);
    let base = xyz(m.albedo);
    let (metallic, transmission) = (m.params.z, m.params.w);
    let (p_spec, p_diff, p_through) = probabilities;
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

/// f (without the cosine) and the pdf of `sample` for local directions (`o.z > 0`): the base,
/// given its `lobes` at `o`, under the coat (`coat`) where its factor `c` is positive (α `ca`).
/// One function for both, so that a shader inlines the base's evaluation once per call.
#[inline]
#[allow(clippy::too_many_arguments)]
fn eval_local(
    m: &Material,
    o: Vec3,
    i: Vec3,
    eta: f32,
    c: f32,
    ca: f32,
    (probabilities, base_sum): ((f32, f32, f32), f32),
) -> (Vec3, f32) {
    let (base, base_pdf) = eval_base(m, o, i, eta, probabilities);
    if !(c > 0.0) {
        return (base, base_pdf);
    }
    let (share, p_coat) = coat_split(c, o, base_sum);
    let (value, pdf) = (base * share, base_pdf * (1.0 - p_coat));
    if i.z <= 0.0 {
        return (value, pdf);
    }
    let (coat_value, coat_pdf) = coat_local(c, ca, o, i);
    (value + coat_value, pdf + p_coat * coat_pdf)
}

#[inline]
pub fn eval(m: &Material, o: Vec3, i: Vec3, front: bool) -> (Vec3, f32) {
    if o.z <= 0.0 {
        return (Vec3::ZERO, 0.0);
    }
    let eta = relative_eta(m.params.y, front);
    let (c, ca) = coat(m, front);
    eval_local(m, o, i, eta, c, ca, lobes(m, o, eta))
}

/// Picks a lobe with `u3`, draws a direction from it from the disk point `disk`, and weighs it
/// by the whole model: f·|cos| / (the mixture's pdf). Directions are local (`material::sample`).
#[inline]
pub fn sample(m: &Material, o: Vec3, front: bool, disk: (f32, f32), u3: f32) -> BsdfSample {
    let eta = relative_eta(m.params.y, front);
    if o.z <= 0.0 {
        return BsdfSample::NONE;
    }
    let a = alpha(m);
    let base_lobes = lobes(m, o, eta);
    let ((p_spec, p_diff, p_through), base_sum) = base_lobes;
    let (c, ca) = coat(m, front);
    // The coat with its probability, else the base with u3 rescaled to [0, 1).
    let mut u3 = u3;
    let mut in_coat = false;
    if c > 0.0 {
        let (_, p_coat) = coat_split(c, o, base_sum);
        in_coat = u3 < p_coat;
        if !in_coat {
            u3 = (u3 - p_coat) / (1.0 - p_coat);
        }
    }
    if !in_coat & (p_spec + p_diff + p_through <= 0.0) {
        return BsdfSample::NONE;
    }
    let specular = in_coat | (u3 < p_spec);
    let diffuse = !specular & (u3 < p_spec + p_diff);
    let i = if diffuse {
        cosine_hemisphere_at(disk)
    } else {
        // One microfacet sample for the coat, the specular lobe and transmission.
        let h = ggx_sample_visible_at(if in_coat { ca } else { a }, o, disk);
        let oh = dot(o, h);
        if specular {
            let i = h * (2.0 * oh) - o;
            // A reflection below the surface is no direction (`eval` would read it as refracted).
            if i.z <= 0.0 {
                return BsdfSample::NONE;
            }
            i
        } else {
            let (_, cos_t) = fresnel_dielectric(oh, eta);
            if (oh <= 0.0) | (cos_t == 0.0) {
                return BsdfSample::NONE;
            }
            let i = refract(o, h, oh, cos_t, eta);
            if i.z >= 0.0 {
                return BsdfSample::NONE;
            }
            i
        }
    };
    if i.z == 0.0 {
        return BsdfSample::NONE;
    }
    weighed(eval_local(m, o, i, eta, c, ca, base_lobes), i)
}

/// The sample of local direction `i` given the whole model's value and pdf there.
#[inline]
fn weighed((value, pdf): (Vec3, f32), i: Vec3) -> BsdfSample {
    if pdf <= 0.0 {
        return BsdfSample::NONE;
    }
    BsdfSample { wi: i, weight: value * (i.z.abs() / pdf), pdf }
}
