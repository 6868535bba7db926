//! Conductors: a smooth mirror or a rough GGX surface, with the exact Fresnel reflectance of a
//! complex index of refraction η + iκ per channel, as Mitsuba 3's `conductor` and
//! `roughconductor` (`distribution = "ggx"`, visible-normal sampling).
use super::microfacet::{ggx_d, ggx_g1, ggx_sample_visible_at, ggx_visible_pdf};
use super::{BsdfSample, DELTA_PDF};
use crate::glam::Vec3;
use crate::layout::Material;
use crate::vecmath::{dot, normalize, xyz};
#[allow(unused_imports)]
use spirv_std::num_traits::Float;

/// Named metals: (name, η, κ) in linear RGB, each channel the index of refraction of the pure
/// metal sampled at a red, green and blue wavelength (from measured spectra; the set LuxRender,
/// Mitsuba 0.5's RGB mode and many renderers since have used). Documented in the README.
#[allow(clippy::excessive_precision)] // the published figures, as printed
pub const CONDUCTOR_PRESETS: [(&str, [f32; 3], [f32; 3]); 5] = [
    ("Au", [0.143119, 0.374957, 1.442479], [3.983160, 2.385721, 1.603215]),
    ("Ag", [0.155265, 0.116723, 0.138342], [4.828181, 3.122249, 2.146961]),
    ("Cu", [0.200438, 0.924033, 1.102212], [3.912949, 2.452848, 2.142188]),
    ("Al", [1.657460, 0.880369, 0.521229], [9.223869, 6.269523, 4.837001]),
    ("Cr", [4.368860, 2.916700, 1.654700], [5.206430, 4.231360, 3.754950]),
];

/// Fresnel reflectance of a conductor for unpolarised light at incidence cosine `cos_i`
/// (the exact expression for a complex index, pbrt-v3's `FrConductor` with η_i = 1), per channel.
#[inline]
pub fn fresnel_conductor(cos_i: f32, eta: Vec3, k: Vec3) -> Vec3 {
    let c = cos_i.clamp(0.0, 1.0);
    Vec3::new(fresnel_channel(c, eta.x, k.x), fresnel_channel(c, eta.y, k.y), fresnel_channel(c, eta.z, k.z))
}

/// One channel of `fresnel_conductor`, in scalar operations (what both devices round alike).
#[inline]
fn fresnel_channel(c: f32, eta: f32, k: f32) -> f32 {
    let cos2 = c * c;
    let sin2 = 1.0 - cos2;
    let eta2 = eta * eta;
    let k2 = k * k;
    // η² − κ² − sin²θ, written without subtracting `sin2 = 1 − cos2`: the SPIR-V optimiser folds
    // x − (1 − y) into (x − 1) + y, which rounds differently from the CPU.
    let t0 = (eta2 - k2 + cos2) - 1.0;
    let a2b2 = (t0 * t0 + 4.0 * eta2 * k2).max(0.0).sqrt();
    let t1 = a2b2 + cos2;
    let a = ((a2b2 + t0) * 0.5).max(0.0).sqrt();
    let t2 = 2.0 * c * a;
    let rs = (t1 - t2) / (t1 + t2);
    let t3 = cos2 * a2b2 + sin2 * sin2;
    let t4 = t2 * sin2;
    let rp = rs * (t3 - t4) / (t3 + t4);
    (rp + rs) * 0.5
}

#[inline]
fn fresnel(m: &Material, cos_i: f32) -> Vec3 {
    fresnel_conductor(cos_i, xyz(m.eta), xyz(m.k))
}

#[inline]
pub fn eval(m: &Material, o: Vec3, i: Vec3) -> (Vec3, f32) {
    let alpha = m.params.x;
    if (alpha == 0.0) | (o.z <= 0.0) | (i.z <= 0.0) {
        return (Vec3::ZERO, 0.0);
    }
    let h = normalize(o + i);
    let value =
        fresnel(m, dot(o, h)) * (ggx_d(alpha, h) * ggx_g1(alpha, o, h) * ggx_g1(alpha, i, h) / (4.0 * o.z * i.z));
    (value, ggx_visible_pdf(alpha, o, h))
}

#[inline]
pub fn sample(m: &Material, o: Vec3, disk: (f32, f32)) -> BsdfSample {
    let alpha = m.params.x;
    if o.z <= 0.0 {
        return BsdfSample::NONE;
    }
    // A smooth mirror reflects `o` about the normal with its whole weight F(o_z); a rough one
    // reflects about a visible normal h. One Fresnel evaluation for both (a shader inlines it
    // per call).
    let mut i = Vec3::new(-o.x, -o.y, o.z);
    let (mut cos, mut g1, mut pdf) = (o.z, 1.0, DELTA_PDF);
    if alpha != 0.0 {
        let h = ggx_sample_visible_at(alpha, o, disk);
        i = h * (2.0 * dot(o, h)) - o;
        if i.z <= 0.0 {
            return BsdfSample::NONE;
        }
        // f·cos/pdf = F·D·G1(o)·G1(i)/(4 o_z) ÷ G1(o)·D/(4 o_z) = F·G1(i).
        (cos, g1, pdf) = (dot(o, h), ggx_g1(alpha, i, h), ggx_visible_pdf(alpha, o, h));
    }
    // × 1 for the mirror: exact.
    BsdfSample { wi: i, weight: fresnel(m, cos) * g1, pdf }
}
