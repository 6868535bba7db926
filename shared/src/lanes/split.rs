//! Sixteen rays against a scene split in two: a few large triangles, tested against all sixteen
//! rays at once (`brute`), and a wide BVH over the others, traversed ray by ray only by the rays
//! that may meet the others' box before their hit among the large ones.
//!
//! A scene of a dense mesh inside a room, a studio box or over a ground plane sends most of its
//! rays from one wall to another: with one BVH over everything, each of them pays a traversal's
//! fixed cost (the shear, the reciprocal, the root's boxes, the ordering of children) and the
//! descent into the wall's leaves. Split, the walls cost a few vector steps shared by sixteen
//! rays, and a ray that misses the mesh's box skips the traversal. The host picks the large
//! triangles by a cost model (`host::bvh::split`) and leaves the split empty where it would not
//! pay.
//!
//! The hit is the whole BVH's bit for bit: the large triangles' closest hit (lowest id on a
//! tie) is carried into the other BVH's traversal as the hit so far, which a triangle there
//! replaces only where it is closer, or as close with a lower id (`kdtree::test_block_run`): brute
//! force over all triangles. The box test skips only rays that cannot meet the box, whatever the
//! rounding of its slab distances.
use super::{brute, Hits, F, LANES, M, U, V3};
use crate::kdtree::Hit;
use crate::layout::{RenderParams, NO_HIT, TRAVERSAL_WIDE_BVH};
use crate::numerics::T_SLACK;
use crate::scene::{SceneView, SplitView};
use crate::wide_bvh::traverse_from;
use core::simd::cmp::{SimdPartialEq, SimdPartialOrd};
use core::simd::num::SimdFloat;

/// Whether the live lanes' rays are cast through the split: there is one (so no alpha masks,
/// which the host checks), the wide BVH is the traversal asked for, and the large triangles are
/// few for the rays (`brute::TRIANGLES_PER_RAY`).
#[inline(always)]
pub fn applies(scene: &SceneView, p: &RenderParams, live: M) -> bool {
    let n = scene.split.large.len();
    (n != 0) & (p.traversal == TRAVERSAL_WIDE_BVH) & brute::pays(n, live) & !scene.alpha_masks
}

/// The lanes whose ray may enter the rest's box at a distance in [0, reach]. A lane whose slab
/// distances are not all finite (a zero or denormal direction component, a non-finite origin)
/// is kept: the traversal decides.
#[inline(always)]
fn may_enter(s: &SplitView, origin: V3, dir: V3, reach: F) -> M {
    let one = F::splat(1.0);
    let slab = |lo: f32, hi: f32, o: F, d: F| {
        let r = one / d;
        let (a, b) = ((F::splat(lo) - o) * r, (F::splat(hi) - o) * r);
        (a.simd_min(b), a.simd_max(b), a.is_finite() & b.is_finite())
    };
    let (nx, fx, okx) = slab(s.rest_min.x, s.rest_max.x, origin.x, dir.x);
    let (ny, fy, oky) = slab(s.rest_min.y, s.rest_max.y, origin.y, dir.y);
    let (nz, fz, okz) = slab(s.rest_min.z, s.rest_max.z, origin.z, dir.z);
    // Conservative as the BVH's own box test (`wide_bvh`): the exit widened and the entry
    // lowered by `T_SLACK`, so a hit on the box's face or at the reach is never skipped.
    let t_in = nx.simd_max(ny).simd_max(nz) * F::splat(1.0 - T_SLACK);
    let t_out = fx.simd_min(fy).simd_min(fz) * F::splat(1.0 + T_SLACK);
    let outside = t_in.simd_gt(t_out) | t_out.simd_lt(F::splat(0.0)) | t_in.simd_gt(reach);
    !(okx & oky & okz & outside)
}

/// The closest hits of the live lanes' rays in (0, ∞).
#[inline(always)]
pub fn closest(scene: &SceneView, origin: V3, dir: V3, live: M) -> Hits {
    let s = scene.split;
    let mut h = brute::cast(s.large, s.large_ids, origin, dir, F::splat(f32::MAX), live, false);
    let todo = live & may_enter(&s, origin, dir, h.t);
    for i in 0..LANES {
        if todo.test(i) {
            let best = Hit { t: h.t[i], triangle: h.triangle[i], u: h.u[i], v: h.v[i], w: h.w[i], nodes: 0, tests: 0 };
            let r = traverse_from::<false>(scene, s.rest, 0, origin.lane(i), dir.lane(i), best, false);
            (h.triangle[i], h.t[i], h.u[i], h.v[i], h.w[i]) = (r.triangle, r.t, r.u, r.v, r.w);
        }
    }
    h
}

/// The live lanes whose ray meets nothing in (0, t_max).
#[inline(always)]
pub fn unblocked(scene: &SceneView, origin: V3, dir: V3, t_max: F, live: M) -> M {
    let s = scene.split;
    let h = brute::cast(s.large, s.large_ids, origin, dir, t_max, live, true);
    let mut open = live & h.triangle.simd_eq(U::splat(NO_HIT));
    let todo = open & may_enter(&s, origin, dir, t_max);
    for i in 0..LANES {
        if todo.test(i) {
            let r = traverse_from::<false>(scene, s.rest, 0, origin.lane(i), dir.lane(i), Hit::miss(t_max[i]), true);
            open.set(i, !r.is_hit());
        }
    }
    open
}
