//! Materials: BSDFs dispatched on `Material::kind` (a tag, with the material an index into the
//! material buffer; pbrt-v4's tagged dispatch without pointers), and one-sided area emission.
//!
//! Every BSDF works with `n`, the shading normal turned toward the side the ray arrived from,
//! `wo`, the unit direction back toward where the ray came from, and `wi`, the direction light
//! arrives from (both pointing away from the surface). `eval` returns the BSDF value without the
//! cosine and the solid-angle pdf of `sample` choosing `wi`; `sample` returns f·|cos|/pdf as the
//! weight. A smooth (delta) lobe has no value to evaluate: `eval` gives zero, and `sample`
//! reports pdf `DELTA_PDF`, which takes the whole MIS weight (`sampling::power_heuristic`).
//!
//! The kinds' own `eval` and `sample` see these directions in the shading frame around `n` (`o`
//! for `wo`, `i` for `wi`, z along `n`): `eval` and `sample` here build the frame once, and
//! `sample` maps its two uniforms onto the unit disk once (`sampling::concentric_disk`), for
//! whichever kind the material is. A shader inlines each of them once, not once per kind.
//!
//! When the variant has one material kind only (`features::Variant::only_material`) the kind is
//! not tested.
mod conductor;
mod dielectric;
mod diffuse;
mod frame;
mod microfacet;
mod plastic;
mod principled;

pub use conductor::{fresnel_conductor, CONDUCTOR_PRESETS};
pub use dielectric::{fresnel_dielectric, refract};
pub use frame::Frame;
pub use microfacet::{ggx_d, ggx_g1, ggx_g1_two_sided, ggx_sample_visible, ggx_visible_pdf};
pub use plastic::{
    fresnel_diffuse_reflectance, plastic_scale, rough_plastic_transmittance, ROUGH_PLASTIC_TABLE_RES,
    ROUGH_PLASTIC_TABLE_WORDS,
};
pub use principled::PRINCIPLED_MIN_ALPHA;

use crate::features::{
    Variant, FEATURE_CONDUCTOR, FEATURE_DIELECTRIC, FEATURE_DIFFUSE, FEATURE_PLASTIC, FEATURE_PRINCIPLED,
};
use crate::glam::Vec3;
use crate::layout::{
    Material, MATERIAL_CONDUCTOR, MATERIAL_DIELECTRIC, MATERIAL_DIFFUSE, MATERIAL_PLASTIC, MATERIAL_PRINCIPLED,
};
use crate::sampling::concentric_disk;
use crate::vecmath::{dot, xyz};

/// The pdf a delta lobe reports: the largest f32, whose square overflows, so that it takes the
/// whole MIS weight. (Not ∞: naga refuses an infinite constant in a shader.)
pub const DELTA_PDF: f32 = f32::MAX;

/// A direction sampled from a BSDF with its weight f·|cos|/pdf and its solid-angle pdf
/// (`DELTA_PDF` for a delta lobe). (Never returned in a tuple: naga rounds this struct's size up
/// to 32 bytes and refuses a member placed after its 28.)
#[derive(Clone, Copy)]
pub struct BsdfSample {
    pub wi: Vec3,
    pub weight: Vec3,
    pub pdf: f32,
}

impl BsdfSample {
    /// No direction: the path ends.
    pub const NONE: BsdfSample = BsdfSample { wi: Vec3::ZERO, weight: Vec3::ZERO, pdf: 0.0 };
}

/// Whether `m` is `kind`, or the variant has no other kind.
#[inline(always)]
fn is(v: Variant, m: &Material, kind: u32, bit: u32) -> bool {
    v.only_material(bit) | (v.has(bit) & (m.kind == kind))
}

/// BSDF value f(wo, wi) (without the cosine) and the pdf of `sample` choosing `wi`. `words`:
/// the texture buffer (`SceneView::textures`), where a rough plastic's table lives.
// Forced on the CPU, like the traversal's leaf test: called, these see the variant's feature
// bits as run-time values and test every kind; inlined into a monomorph, the dispatch folds to
// the kinds the variant has.
#[cfg_attr(not(target_arch = "spirv"), inline(always))]
#[cfg_attr(target_arch = "spirv", inline)]
#[allow(clippy::too_many_arguments)]
pub fn eval(v: Variant, m: &Material, words: &[u32], n: Vec3, wo: Vec3, wi: Vec3, front: bool) -> (Vec3, f32) {
    // The kinds work in the shading frame; it is built once here, not once per kind in a shader.
    let f = Frame::new(n);
    let (o, i) = (f.to_local(wo), f.to_local(wi));
    if is(v, m, MATERIAL_DIFFUSE, FEATURE_DIFFUSE) {
        return diffuse::eval(m, i);
    }
    if is(v, m, MATERIAL_CONDUCTOR, FEATURE_CONDUCTOR) {
        return conductor::eval(m, o, i);
    }
    if is(v, m, MATERIAL_DIELECTRIC, FEATURE_DIELECTRIC) {
        return dielectric::eval(m, o, i, front);
    }
    if is(v, m, MATERIAL_PLASTIC, FEATURE_PLASTIC) {
        return plastic::eval(m, words, o, i);
    }
    if is(v, m, MATERIAL_PRINCIPLED, FEATURE_PRINCIPLED) {
        return principled::eval(m, o, i, front);
    }
    (Vec3::ZERO, 0.0)
}

/// Samples `wi` for outgoing direction `wo` from uniforms `u1`, `u2` (the direction) and `u3`
/// (the lobe, where there is a choice); `front`: the ray arrived on the counter-clockwise
/// (outside) side, which a dielectric needs to know which medium is which; `words`: as for `eval`. `u3` must be
/// independent of `u1`, `u2` (`rng::Sampler::independent_after`) where `picks_lobe`.
#[cfg_attr(not(target_arch = "spirv"), inline(always))]
#[cfg_attr(target_arch = "spirv", inline)]
#[allow(clippy::too_many_arguments)]
pub fn sample(
    v: Variant,
    m: &Material,
    words: &[u32],
    n: Vec3,
    wo: Vec3,
    front: bool,
    u1: f32,
    u2: f32,
    u3: f32,
) -> BsdfSample {
    // Every kind draws its direction (a cosine-weighted one or a visible microfacet normal) from
    // the same point of the unit disk: mapped once here, a shader inlines the map once, not once
    // per kind and lobe.
    let disk = concentric_disk(u1, u2);
    // Likewise one shading frame: the kinds sample a local direction, turned to the world once.
    let f = Frame::new(n);
    let o = f.to_local(wo);
    let s = if is(v, m, MATERIAL_DIFFUSE, FEATURE_DIFFUSE) {
        diffuse::sample(m, disk)
    } else if is(v, m, MATERIAL_CONDUCTOR, FEATURE_CONDUCTOR) {
        conductor::sample(m, o, disk)
    } else if is(v, m, MATERIAL_DIELECTRIC, FEATURE_DIELECTRIC) {
        dielectric::sample(m, o, front, u1, disk, u3)
    } else if is(v, m, MATERIAL_PLASTIC, FEATURE_PLASTIC) {
        plastic::sample(m, words, o, disk, u3)
    } else if is(v, m, MATERIAL_PRINCIPLED, FEATURE_PRINCIPLED) {
        principled::sample(m, o, front, disk, u3)
    } else {
        BsdfSample::NONE
    };
    // A sampled direction is a unit vector; `NONE` keeps its zero direction exactly.
    let none = (s.wi.x == 0.0) & (s.wi.y == 0.0) & (s.wi.z == 0.0);
    BsdfSample { wi: if none { Vec3::ZERO } else { f.to_world(s.wi) }, ..s }
}

/// Whether every lobe of `m` is a delta (a smooth mirror): light sampling cannot hit it.
#[inline]
pub fn is_delta(v: Variant, m: &Material) -> bool {
    (is(v, m, MATERIAL_CONDUCTOR, FEATURE_CONDUCTOR) | is(v, m, MATERIAL_DIELECTRIC, FEATURE_DIELECTRIC))
        & (m.params.x == 0.0)
}

/// Whether sampling `m` picks a lobe with its third uniform (`sample`'s `u3`): a rough
/// dielectric, plastic, principled.
#[inline]
pub fn picks_lobe(v: Variant, m: &Material) -> bool {
    (is(v, m, MATERIAL_DIELECTRIC, FEATURE_DIELECTRIC) & (m.params.x > 0.0))
        | is(v, m, MATERIAL_PLASTIC, FEATURE_PLASTIC)
        | is(v, m, MATERIAL_PRINCIPLED, FEATURE_PRINCIPLED)
}

/// Whether `m` may send a path through the surface (the next ray starts on the far side).
#[inline]
pub fn transmits(v: Variant, m: &Material) -> bool {
    is(v, m, MATERIAL_DIELECTRIC, FEATURE_DIELECTRIC)
        | (is(v, m, MATERIAL_PRINCIPLED, FEATURE_PRINCIPLED) & (m.params.w > 0.0))
}

/// The absorption coefficient per unit length inside `m` (Beer–Lambert; a principled
/// material's KHR_materials_volume, in `k.xyz`), zero where nothing absorbs.
#[inline]
pub fn absorption(v: Variant, m: &Material) -> Vec3 {
    if is(v, m, MATERIAL_PRINCIPLED, FEATURE_PRINCIPLED) {
        xyz(m.k)
    } else {
        Vec3::ZERO
    }
}

/// The material's colour for an albedo image: a diffuse, plastic or principled material's base
/// colour, a conductor's reflectance at normal incidence, a dielectric's white (it lets
/// everything through or reflects it).
#[inline]
pub fn albedo(v: Variant, m: &Material) -> Vec3 {
    if is(v, m, MATERIAL_CONDUCTOR, FEATURE_CONDUCTOR) {
        // ((η − 1)² + κ²) / ((η + 1)² + κ²): `fresnel_conductor` at normal incidence, written
        // out (with the cosine a constant 1 a shader compiler simplifies the general form).
        let (eta, k) = (xyz(m.eta), xyz(m.k));
        let below = (eta - Vec3::ONE) * (eta - Vec3::ONE) + k * k;
        let above = (eta + Vec3::ONE) * (eta + Vec3::ONE) + k * k;
        return below / above;
    }
    if is(v, m, MATERIAL_DIELECTRIC, FEATURE_DIELECTRIC) {
        return Vec3::ONE;
    }
    xyz(m.albedo)
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
