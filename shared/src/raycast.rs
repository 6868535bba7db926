//! Ray queries behind one switch: the closest hit or any hit, by the full-stack or the
//! short-stack traversal, with the traversal's work.
//!
//! The integrator calls `closest` and `any` so the traversal is a run-time choice on both
//! devices (`RenderParams::traversal`). The ray-casting kernel runs `cast_ray` per invocation
//! and the CPU runs it per ray, so a batch of rays can be compared device against device ray by
//! ray, and rays/s can be measured for the primary, ambient-occlusion and diffuse-bounce rays of
//! Aila & Laine, "Understanding the Efficiency of Ray Traversal on GPUs" (HPG 2009).
//!
//! `query_recorded` is the one query behind all of them, telling a `Recorder` which nodes the
//! traversal visits; the others pass `NoRecord`.
use crate::glam::Vec3;
use crate::kdtree::Hit;
use crate::layout::{RayQuery, RayResult, RAY_ALPHA_MASKS, RAY_ANY_HIT, RAY_SHORT_STACK, TRAVERSAL_SHORT_STACK};
use crate::record::{NoRecord, Recorder};
use crate::scene::SceneView;
use crate::short_stack::{self, SHORT_STACK};
use crate::vecmath::xyz;

/// A hit with the number of restarts the short stack needed (0 for the full stack).
#[derive(Clone, Copy)]
pub struct Traced {
    pub hit: Hit,
    pub restarts: u32,
}

/// The closest hit (or, with `any_hit`, any hit) with t in (0, t_max) by the chosen traversal.
/// Inlined always on the CPU, so that `cast_ray` in the AVX-512 copy compiles the traversal for
/// it (a plain `#[inline]` left it a call to the baseline code).
#[cfg_attr(not(target_arch = "spirv"), inline(always))]
#[cfg_attr(target_arch = "spirv", inline)]
pub fn query(scene: &SceneView, traversal: u32, origin: Vec3, dir: Vec3, t_max: f32, any_hit: bool) -> Traced {
    query_recorded(scene, traversal, origin, dir, t_max, any_hit, &mut NoRecord)
}

/// `query`, telling `rec` of every k-d node the traversal visits (`Recorder::node`).
/// Inlined, with the wide BVH's traversal, into the integrator (`render_pixels_for`).
#[inline(always)]
pub fn query_recorded<R: Recorder>(
    scene: &SceneView,
    traversal: u32,
    origin: Vec3,
    dir: Vec3,
    t_max: f32,
    any_hit: bool,
    rec: &mut R,
) -> Traced {
    #[cfg(not(target_arch = "spirv"))]
    if traversal == crate::layout::TRAVERSAL_WIDE_BVH {
        // The wide BVH's nodes are not the k-d tree's: `rec` hears of none.
        return Traced { hit: crate::wide_bvh::traverse(scene, origin, dir, t_max, any_hit), restarts: 0 };
    }
    // One call for both stacks: a shader inlines the traversal once per query (`short_stack`).
    let short = traversal == TRAVERSAL_SHORT_STACK;
    let s = short_stack::traverse::<SHORT_STACK, R>(scene, origin, dir, t_max, any_hit, short, rec);
    Traced { hit: s.hit, restarts: s.restarts }
}

/// The closest hit with t in (0, t_max) by the chosen traversal.
#[inline]
pub fn closest(scene: &SceneView, traversal: u32, origin: Vec3, dir: Vec3, t_max: f32) -> Traced {
    query(scene, traversal, origin, dir, t_max, false)
}

/// Any hit with t in (0, t_max) by the chosen traversal.
#[inline]
pub fn any(scene: &SceneView, traversal: u32, origin: Vec3, dir: Vec3, t_max: f32) -> Traced {
    query(scene, traversal, origin, dir, t_max, true)
}

/// One ray of a batch; alpha masks count where the query asks for them (`RAY_ALPHA_MASKS`) and
/// the scene view tests them. Inlined always, like the traversal, for the CPU's AVX-512 copy.
#[inline(always)]
pub fn cast_ray(scene: &SceneView, q: &RayQuery) -> RayResult {
    let masks = scene.alpha_masks & ((q.flags & RAY_ALPHA_MASKS) != 0);
    let scene = &SceneView { alpha_masks: masks, ..*scene };
    let (o, d) = (xyz(q.origin), xyz(q.dir));
    let traversal = if (q.flags & RAY_SHORT_STACK) != 0 { TRAVERSAL_SHORT_STACK } else { 0 };
    #[cfg(not(target_arch = "spirv"))]
    let traversal =
        if (q.flags & crate::layout::RAY_WIDE_BVH) != 0 { crate::layout::TRAVERSAL_WIDE_BVH } else { traversal };
    let r = query(scene, traversal, o, d, q.t_max, (q.flags & RAY_ANY_HIT) != 0);
    RayResult {
        t: r.hit.t,
        triangle: r.hit.triangle,
        nodes: r.hit.nodes,
        tests: r.hit.tests,
        restarts: r.restarts,
        _pad: [0; 3],
    }
}

/// The rays of `qs` (at most `wide_packet::PACKET`) into `out`, as `cast_ray` casts each: in one
/// packet (`wide_packet`) where they all ask for the wide BVH with the same flags, else one by
/// one. CPU only; inlined always, like `cast_ray`, for the AVX-512 copy.
#[cfg(not(target_arch = "spirv"))]
#[inline(always)]
pub fn cast_packet(scene: &SceneView, qs: &[RayQuery], out: &mut [RayResult]) {
    use crate::wide_packet::{self, PACKET};
    let flags = qs.first().map_or(0, |q| q.flags);
    let packet = (qs.len() <= PACKET)
        & (out.len() >= qs.len())
        & ((flags & crate::layout::RAY_WIDE_BVH) != 0)
        & qs.iter().all(|q| q.flags == flags);
    if !packet {
        for (q, r) in qs.iter().zip(out.iter_mut()) {
            *r = cast_ray(scene, q);
        }
        return;
    }
    let masks = scene.alpha_masks & ((flags & RAY_ALPHA_MASKS) != 0);
    let scene = &SceneView { alpha_masks: masks, ..*scene };
    let mut origin = [Vec3::ZERO; PACKET];
    let mut dir = [Vec3::Z; PACKET];
    let mut t_max = [0.0; PACKET];
    for (i, q) in qs.iter().enumerate() {
        origin[i] = xyz(q.origin);
        dir[i] = xyz(q.dir);
        t_max[i] = q.t_max;
    }
    let hits = wide_packet::traverse(scene, &origin, &dir, &t_max, qs.len(), (flags & RAY_ANY_HIT) != 0);
    for (h, r) in hits.iter().zip(out.iter_mut()).take(qs.len()) {
        *r = RayResult { t: h.t, triangle: h.triangle, nodes: h.nodes, tests: h.tests, restarts: 0, _pad: [0; 3] };
    }
}
