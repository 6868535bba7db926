//! Next-event estimation's light sample (Veach & Guibas 1995; pbrt-v4 §13.4): where the sample
//! lies on the light it picked, by the light's kind (an emitting triangle's area sample, the
//! environment map by its distribution, a punctual light, a delta), what arrives from there and
//! its density (`LightDirection`); then one evaluation of the BSDF toward it at the shading point
//! (`Shading`), its MIS weight and its shadow ray, not yet traced (`light_sample_toward`, a
//! `shadow::LightSample`). A shader inlines each of these once: the integrator's vertex calls
//! them at one place for every kind of light (README, "Shader size").
use crate::environment;
use crate::features::{Variant, FEATURE_ENVIRONMENT_MAP, FEATURE_PUNCTUAL};
use crate::glam::Vec3;
use crate::layout::{LIGHT_ENVIRONMENT_BIT, LIGHT_OFFSET_MASK};
use crate::material::eval;
use crate::numerics::offset_ray_origin;
use crate::punctual;
use crate::record::{LightEvent, LIGHT_BLOCKED, LIGHT_INVALID};
use crate::sampling::{light_point, power_heuristic, power_heuristic3};
use crate::scene::SceneView;
use crate::shadow::{LightSample, ShadowRay};
use crate::surface::{consistent, emission_at};
use crate::vecmath::{dot, length_squared};
#[allow(unused_imports)]
use spirv_std::num_traits::Float;

/// Where next-event estimation's light sample lies, before the BSDF is evaluated toward it.
#[derive(Clone, Copy)]
pub(crate) struct LightDirection {
    /// The unit direction toward the sample.
    pub(crate) wi: Vec3,
    /// The radiance arriving along `wi` if nothing blocks it.
    incident: Vec3,
    /// The sample's solid-angle density (a punctual light's pick probability).
    light_pdf: f32,
    /// Where the shadow ray ends (unless `infinite`), and the point the recorder is told of.
    target: Vec3,
    point: Vec3,
    /// A triangle's pick probability over its area (the connection's weight needs it).
    pub(crate) pa: f32,
    /// The light lies at infinity (the shadow ray has no end), is a delta (takes its whole
    /// weight), and can be sampled from here at all.
    infinite: bool,
    delta: bool,
    ok: bool,
    /// The recorder is told of `light_pdf` also where the sample is not taken.
    tell_pdf: bool,
}

/// The shading point a light sample is taken at: position, the spawn point on the side of the
/// flat normal `nf`, the position's rounding error, the shading normal, the direction toward
/// the ray's origin and the side hit.
#[derive(Clone, Copy)]
pub(crate) struct Shading {
    pub pos: Vec3,
    pub spawn: Vec3,
    pub error: Vec3,
    pub nf: Vec3,
    pub ns: Vec3,
    pub wo: Vec3,
    pub front: bool,
}

/// A point on emitting triangle `light` (uniforms `u1`, `u2`) seen from `pos`.
#[inline(always)]
pub(crate) fn triangle_light_direction(
    scene: &SceneView,
    v: Variant,
    light: &crate::layout::Light,
    pos: Vec3,
    u1: f32,
    u2: f32,
) -> LightDirection {
    let lp = light_point(&scene.triangles[light.triangle as usize], u1, u2);
    let (on_light, nl) = (lp.at, lp.n);
    let q = on_light.p;
    let to_light = q - pos;
    let dist2 = length_squared(to_light);
    let wi = to_light * (1.0 / dist2.sqrt());
    let cos_l = -dot(nl, wi);
    let lmat = &scene.materials[scene.info[light.triangle as usize].material as usize];
    LightDirection {
        wi,
        incident: emission_at(scene, v, lmat, light.triangle, lp.b),
        light_pdf: light.pmf * dist2 / (cos_l * light.area),
        target: offset_ray_origin(q, on_light.error, nl),
        point: q,
        pa: light.pmf / light.area,
        infinite: false,
        delta: false,
        ok: (cos_l > 0.0) & (dist2 > 0.0),
        tell_pdf: false,
    }
}

/// A sample of a light-table entry that is not a triangle (`kind`: `LIGHT_NOT_TRIANGLE |
/// offset`, with `LIGHT_ENVIRONMENT_BIT` for the environment map), picked with probability
/// `pmf`: the map sampled by its distribution, or a punctual light, a delta.
#[inline(always)]
pub(crate) fn other_light_direction(
    scene: &SceneView,
    v: Variant,
    kind: u32,
    pmf: f32,
    pos: Vec3,
    u1: f32,
    u2: f32,
) -> LightDirection {
    let o = kind & LIGHT_OFFSET_MASK;
    let env = v.has(FEATURE_ENVIRONMENT_MAP) & (kind & LIGHT_ENVIRONMENT_BIT != 0);
    let mut d = LightDirection {
        wi: Vec3::Z,
        incident: Vec3::ZERO,
        light_pdf: 0.0,
        target: pos,
        point: pos,
        pa: 0.0,
        infinite: true,
        delta: false,
        ok: false,
        tell_pdf: true,
    };
    if env {
        let s = environment::sample(scene.textures, o, u1, u2);
        d.wi = s.wi;
        d.incident = s.radiance;
        d.light_pdf = pmf * s.pdf;
    } else if v.has(FEATURE_PUNCTUAL) {
        let s = punctual::sample(scene.textures, o, pos);
        d.wi = s.wi;
        d.incident = s.incident;
        d.light_pdf = pmf;
        d.target = s.target;
        d.infinite = s.infinite;
        d.delta = true;
    }
    d.point = d.target;
    let visible = (d.incident.x > 0.0) | (d.incident.y > 0.0) | (d.incident.z > 0.0);
    d.ok = visible & (d.light_pdf > 0.0);
    d
}

/// Next-event estimation's sample `d` of light `index` (`kind`, its triangle or table entry)
/// at shading point `at`: the BSDF evaluated toward it, the shadow ray (not yet traced) and the
/// contribution for a path of throughput `beta`, MIS-weighted against the BSDF, or with `three`
/// against the BSDF and the connection (whose density is `q2`); a delta takes its whole weight.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn light_sample_toward(
    scene: &SceneView,
    v: Variant,
    beta: Vec3,
    mat: &crate::layout::Material,
    d: &LightDirection,
    index: u32,
    kind: u32,
    at: &Shading,
    three: bool,
    q2: f32,
) -> LightSample {
    let wi = d.wi;
    let (f, pdf_bsdf) = eval(v, mat, scene.textures, at.ns, at.wo, wi, at.front);
    let mut s = LightSample {
        event: LightEvent {
            status: LIGHT_INVALID,
            light: index,
            triangle: kind,
            point: d.point,
            light_pdf: if d.tell_pdf { d.light_pdf } else { 0.0 },
            bsdf_pdf: pdf_bsdf,
            mis_weight: 0.0,
            contribution: Vec3::ZERO,
        },
        ray: ShadowRay::NONE,
        added: Vec3::ZERO,
    };
    if d.ok & (pdf_bsdf > 0.0) & consistent(v, at.nf, at.ns, wi) {
        let cos_i = dot(at.ns, wi);
        // A light behind a transmitting surface is seen through it: the shadow ray leaves from
        // the far side.
        let from = if dot(at.nf, wi) < 0.0 { offset_ray_origin(at.pos, at.error, -at.nf) } else { at.spawn };
        s.ray = if d.infinite { ShadowRay::new(from, wi, f32::MAX) } else { ShadowRay::toward(from, d.target) };
        let weight = if d.delta {
            1.0
        } else if three {
            power_heuristic3(d.light_pdf, pdf_bsdf, q2)
        } else {
            power_heuristic(d.light_pdf, pdf_bsdf)
        };
        s.event.status = LIGHT_BLOCKED;
        s.event.light_pdf = d.light_pdf;
        s.event.mis_weight = weight;
        s.added = beta * f * d.incident * (cos_i.abs() * weight / d.light_pdf);
    }
    s
}

/// Next-event estimation toward a light-table entry that is not a triangle (`kind`:
/// `LIGHT_NOT_TRIANGLE | offset`, with `LIGHT_ENVIRONMENT_BIT` for the environment map): the map
/// is sampled by its distribution and MIS-weighted against the BSDF; a punctual light is a delta
/// and takes its whole weight. Returns the sample with its shadow ray, not yet traced, and its
/// contribution for a path of throughput `beta` (the lane integrator's, lane by lane).
#[cfg(not(target_arch = "spirv"))]
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn other_light_sample(
    scene: &SceneView,
    v: Variant,
    beta: Vec3,
    mat: &crate::layout::Material,
    kind: u32,
    pmf: f32,
    index: u32,
    at: &Shading,
    u1: f32,
    u2: f32,
) -> LightSample {
    let d = other_light_direction(scene, v, kind, pmf, at.pos, u1, u2);
    light_sample_toward(scene, v, beta, mat, &d, index, kind, at, false, 0.0)
}
