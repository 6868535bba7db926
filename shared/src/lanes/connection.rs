//! `crate::connection` for sixteen samples in lockstep: each lane's light subpath and the
//! connections of its eye vertices, the same sums as the scalar functions bit for bit.
use super::integrator::{gather, light_points, pick_lights, trace_closest, unblocked, LightPoints};
use super::sampler::LaneSampler;
use super::warp::{cosine_hemisphere, offset_ray_origin, orthonormal_basis, power_heuristic3, weights};
use super::{sqrt, F, M, U, V3};
use crate::connection::CONNECT_TAG;
use crate::layout::{RenderParams, LIGHT_NOT_TRIANGLE, NO_HIT};
use crate::sampling::INV_PI;
use crate::scene::SceneView;
use core::simd::cmp::{SimdPartialEq, SimdPartialOrd};
use core::simd::num::SimdFloat;
use core::simd::Select;

/// The first vertex of each lane's light subpath: a point on an emitting triangle (picked as
/// next-event estimation picks it), a cosine-distributed direction, the surface it reaches.
pub(super) struct LightVertex {
    valid: M,
    pos: V3,
    error: F,
    n: V3,
    albedo: V3,
    /// Unit direction from the vertex to the point on the light.
    to_light: V3,
    dist2: F,
    cos_l: F,
    /// The light point's area density (pmf / area).
    pa: F,
    /// Emission / (pi pa), as `crate::connection::LightVertex`'s.
    power: V3,
}

impl LightVertex {
    pub(super) fn none() -> Self {
        let z = F::splat(0.0);
        LightVertex {
            valid: M::splat(false),
            pos: V3::ZERO,
            error: z,
            n: V3::ZERO,
            albedo: V3::ZERO,
            to_light: V3::ZERO,
            dist2: z,
            cos_l: z,
            pa: z,
            power: V3::ZERO,
        }
    }
}

#[inline(always)]
pub(super) fn light_vertices(
    scene: &SceneView,
    p: &RenderParams,
    many: bool,
    rng: &LaneSampler,
    live: M,
) -> LightVertex {
    let zero = F::splat(0.0);
    let [ua, ub, uc, ud] = rng.independent_4d(CONNECT_TAG);
    let picks = pick_lights(scene, many, ua, live);
    let ok = live & U::from_array(picks.triangle).simd_lt(U::splat(LIGHT_NOT_TRIANGLE));
    let LightPoints { g: lg, q, error: q_error, n: nl, .. } = light_points(scene, &picks.triangle, ok, picks.u, ub);
    let local = cosine_hemisphere(uc, ud);
    let (tb, bb) = orthonormal_basis(nl);
    let dir = tb.scale(local.x) + bb.scale(local.y) + nl.scale(local.z);
    let ok = ok & local.z.simd_gt(zero) & lg.emission.any_positive();
    let origin = offset_ray_origin(q, q_error, nl);
    let hits = trace_closest(scene, p, origin, dir, ok, false);
    let hit = hits.triangle.simd_ne(U::splat(NO_HIT)) & ok;
    let yg = gather(scene, &hits.triangle.to_array(), hit);
    let b = weights(hits.u, hits.v, hits.w);
    let (pos, error) = yg.tris.interpolate(b.0, b.1, b.2);
    let len2 = dir.dot(dir);
    // Lanes without a light point carry 0, as no pick at all leaves them.
    let pa = ok.select(picks.pmf / picks.area, zero);
    LightVertex {
        valid: hit & yg.albedo.any_positive(),
        pos,
        error,
        n: yg.tris.n,
        albedo: yg.albedo,
        to_light: -dir.scale(F::splat(1.0) / sqrt(len2)),
        dist2: hits.t * hits.t * len2,
        cos_l: local.z,
        pa,
        power: lg.emission.scale(F::splat(INV_PI) / pa),
    }
}

/// The connection strategy at an eye vertex (Lambertian, flat normal `nf` toward the ray's
/// origin): its path through the light subpath's vertex, MIS-weighted against the path
/// tracer's two ways of making the same path.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn connect(
    scene: &SceneView,
    p: &RenderParams,
    lv: &LightVertex,
    alive: M,
    pos: V3,
    spawn: V3,
    nf: V3,
    albedo: V3,
    beta: V3,
    radiance: &mut V3,
) {
    let zero = F::splat(0.0);
    let d = lv.pos - pos;
    let dist2 = d.dot(d);
    let w = d.scale(F::splat(1.0) / sqrt(dist2));
    let cos_e = nf.dot(w);
    let cos_ye = lv.n.dot(w);
    let nfy = V3::select(cos_ye.simd_lt(zero), lv.n, -lv.n);
    let cos_yl = nfy.dot(lv.to_light);
    let valid = alive & lv.valid & cos_e.simd_gt(zero) & cos_yl.simd_gt(zero) & dist2.simd_gt(zero);
    if !valid.any() {
        return;
    }
    let geo = cos_e * cos_ye.abs() / dist2;
    let q0 = cos_yl * F::splat(INV_PI);
    let q1 = lv.pa * lv.dist2 / lv.cos_l;
    let q2 = lv.pa * cos_yl / geo;
    let w2 = power_heuristic3(q2, q0, q1);
    let target = offset_ray_origin(lv.pos, lv.error, nfy);
    let open = unblocked(scene, p, spawn, target - spawn, valid);
    let added = (beta * albedo * lv.albedo * lv.power).scale(geo * w2);
    *radiance = V3::select(open, *radiance + added, *radiance);
}
