//! `crate::connection` for sixteen samples in lockstep: each lane's light subpath and the
//! connections of its eye vertices, the same sums as the scalar functions bit for bit.
use super::integrator::{gather, light_points, pick_lights, trace_closest, unblocked, LightPoints};
use super::sampler::LaneSampler;
use super::warp::{cosine_hemisphere, offset_ray_origin, orthonormal_basis, power_heuristic3, weights};
use super::{sqrt, F, LANES, M, U, V3};
use crate::connection::{
    pool_candidates, CONNECT_TAG, POOL_BLOCK, POOL_CANDIDATES, POOL_PICK_TAG, POOL_SAMPLES, POOL_SLOTS, POOL_STRIDE,
    POOL_WINDOW_BITS, POOL_WINDOW_TAG,
};
use crate::layout::{RenderParams, LIGHT_NOT_TRIANGLE, NO_HIT};
use crate::sampling::INV_PI;
use crate::scene::SceneView;
use core::simd::cmp::{SimdPartialEq, SimdPartialOrd};
use core::simd::num::SimdFloat;
use core::simd::num::SimdUint;
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

/// `crate::connection::Link` for sixteen segments.
struct Link {
    ok: M,
    geo: F,
    cos_yl: F,
    behind: M,
}

impl Link {
    #[inline(always)]
    fn new(pos: V3, nf: V3, y: V3, ny: V3, ny_to_light: F) -> Link {
        let zero = F::splat(0.0);
        let d = y - pos;
        let dist2 = d.dot(d);
        let w = d.scale(F::splat(1.0) / sqrt(dist2));
        let cos_e = nf.dot(w);
        let cos_ye = ny.dot(w);
        let behind = cos_ye.simd_lt(zero);
        let cos_yl = behind.select(ny_to_light, -ny_to_light);
        Link {
            ok: cos_e.simd_gt(zero) & cos_yl.simd_gt(zero) & dist2.simd_gt(zero),
            geo: cos_e * cos_ye.abs() / dist2,
            cos_yl,
            behind,
        }
    }

    #[inline(always)]
    fn weight(&self, pa: F, q1: F, kappa: F) -> F {
        let q0 = self.cos_yl * F::splat(INV_PI);
        let q2 = pa * self.cos_yl / self.geo * kappa;
        power_heuristic3(q2, q0, q1)
    }
}

/// `crate::connection::PooledLink` for sixteen segments, without its side (`behind`), which
/// `connect_pooled` makes again for the picked candidate alone.
struct PooledLink {
    ok: M,
    term: F,
}

impl PooledLink {
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn new(pos: V3, nf: V3, y: V3, ny: V3, ny_to_light: F, inv_p: F, q01: F) -> PooledLink {
        let zero = F::splat(0.0);
        let d = y - pos;
        let dist2 = d.dot(d);
        let (cos_e, cos_ye) = (nf.dot(d), ny.dot(d));
        let behind = cos_ye.simd_lt(zero);
        let cos_yl = behind.select(ny_to_light, -ny_to_light);
        let inv = F::splat(1.0) / dist2;
        let geo = cos_e * inv * (cos_ye.abs() * inv);
        let r = geo * inv_p;
        let term = geo / (F::splat(1.0) + q01 * (r * r));
        PooledLink { ok: cos_e.simd_gt(zero) & cos_yl.simd_gt(zero) & dist2.simd_gt(zero), term }
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
    let link = Link::new(pos, nf, lv.pos, lv.n, lv.n.dot(lv.to_light));
    let valid = alive & lv.valid & link.ok;
    if !valid.any() {
        return;
    }
    let w2 = link.weight(lv.pa, lv.pa * lv.dist2 / lv.cos_l, F::splat(1.0));
    let target = offset_ray_origin(lv.pos, lv.error, V3::select(link.behind, lv.n, -lv.n));
    let open = unblocked(scene, p, spawn, target - spawn, valid);
    let added = (beta * albedo * lv.albedo * lv.power).scale(link.geo * w2);
    *radiance = V3::select(open, *radiance + added, *radiance);
}

/// `crate::connection::connect_pooled` for sixteen eye vertices: each lane weighs its own
/// candidates from its own block's pool, picks one and casts its shadow ray; the same sums bit
/// for bit. Where each half of the group (lanes 0..8, 8..16) holds one block of one pixel,
/// eight consecutive samples from a multiple of `POOL_SAMPLES` (a pixel's sixteen samples, or
/// two pixels' eight), the half reads a field of its candidates `j` as one run of eight floats:
/// its samples share a window and their slots follow each other. Other groups gather.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn connect_pooled(
    scene: &SceneView,
    p: &RenderParams,
    rng: &LaneSampler,
    bounce: u32,
    alive: M,
    pos: V3,
    spawn: V3,
    nf: V3,
    albedo: V3,
    beta: V3,
    radiance: &mut V3,
) {
    const _: () = assert!(POOL_STRIDE as usize == LANES && 2 * POOL_SAMPLES == POOL_STRIDE);
    let zero = F::splat(0.0);
    let inf = F::splat(f32::INFINITY);
    let u = rng.independent_4d(POOL_PICK_TAG + bounce)[0];
    let window = pool_windows(rng.group_bits(POOL_WINDOW_TAG + bounce, POOL_STRIDE));
    let records = scene.light_pool.records;
    let live = alive;
    let sample = rng.sample();
    let lane = sample % U::splat(POOL_STRIDE);
    let base = (sample / U::splat(POOL_SAMPLES) - U::splat(scene.light_pool.first_block)) * U::splat(POOL_BLOCK as u32);
    // Each half one block of one pixel: lane `8h + i` holds sample `8k + i` of the half's pixel.
    const HALF: usize = LANES / 2;
    const _: () = assert!(POOL_SAMPLES as usize == HALF);
    let pixel = rng.pixel();
    let step = U::from_array(core::array::from_fn(|i| (i % HALF) as u32));
    let firsts = U::from_array(core::array::from_fn(|i| sample[i / HALF * HALF]));
    let pixels = U::from_array(core::array::from_fn(|i| pixel[i / HALF * HALF]));
    let halves = (sample == firsts + step)
        & (pixel == pixels)
        & sample[0].is_multiple_of(POOL_SAMPLES)
        & sample[HALF].is_multiple_of(POOL_SAMPLES);
    let enable = live.cast::<isize>();
    // Field `f` of each lane's candidate in slot `at` (the window's row plus the lane).
    let gathered = |at: U, f: usize| {
        let i = (base + U::splat((f * POOL_SLOTS as usize) as u32) + at).cast::<usize>();
        F::gather_select(records, enable, i, zero)
    };
    // Each half's block, where both halves are runs and their blocks in the pool, a fixed
    // length, so that a run's bounds are known.
    let block = |h: usize| {
        let lo = base[h * HALF] as usize;
        records.get(lo..lo + POOL_BLOCK).and_then(|r| <&[f32; POOL_BLOCK]>::try_from(r).ok())
    };
    let blocks = if halves { block(0).zip(block(1)) } else { None };
    // Field `f` of each half's candidates in slots `at` (the window's row plus the lane): one run
    // of eight floats from the half's first lane's slot. That slot is a multiple of eight, at most
    // `POOL_SLOTS - 8`, already; the mask changes nothing and only bounds the index.
    let runs = |(b0, b1): (&[f32; POOL_BLOCK], &[f32; POOL_BLOCK]), at: U, f: usize| {
        let mut v = [0.0f32; LANES];
        for (h, b) in [b0, b1].into_iter().enumerate() {
            let i = f * POOL_SLOTS as usize + (at[h * HALF] as usize & (POOL_SLOTS as usize - HALF));
            v[h * HALF..][..HALF].copy_from_slice(&b[i..][..HALF]);
        }
        F::from_array(v)
    };
    // Each candidate's weight and geometry term; the picked one's contribution and side are
    // made again from its record after the pick, by the same operations, so the loop keeps
    // two numbers a candidate.
    let mut w = [zero; POOL_CANDIDATES];
    let mut terms = [zero; POOL_CANDIDATES];
    let mut sum = zero;
    let beta_albedo = beta * albedo;
    let candidates = pool_candidates(bounce);
    for j in 0..candidates {
        let row = (window + U::splat(POOL_STRIDE * j as u32)) & U::splat(POOL_SLOTS - 1);
        let at = row + lane;
        let field = |f: usize| match blocks {
            Some(b) => runs(b, at, f),
            None => gathered(at, f),
        };
        let y = V3::new(field(0), field(1), field(2));
        let ny = V3::new(field(3), field(4), field(5));
        let link = PooledLink::new(pos, nf, y, ny, field(6), field(7), field(8));
        let ok = live & link.ok;
        if !ok.any() {
            continue;
        }
        let bw = beta_albedo * V3::new(field(9), field(10), field(11));
        let wj = (bw.x + bw.y + bw.z) * link.term;
        let keep = ok & wj.simd_gt(zero) & wj.simd_lt(inf);
        w[j] = keep.select(wj, zero);
        terms[j] = link.term;
        sum = keep.select(sum + wj, sum);
    }
    let go = live & sum.simd_gt(zero) & sum.simd_lt(inf);
    if !go.any() {
        return;
    }
    // The pick, lane by lane as `connect_pooled` walks the candidates. Subtracting a weight of
    // zero leaves `pick` as it is, and its value after the stop is not read, so the one chain
    // that runs from candidate to candidate is the subtraction.
    let mut pick = u * sum;
    let mut y = U::splat(0);
    let (mut wy, mut ty) = (F::splat(1.0), zero);
    let mut found = M::splat(false);
    for j in 0..candidates {
        let wj = w[j];
        let take = !found & wj.simd_gt(zero);
        y = take.select(U::splat(j as u32), y);
        wy = take.select(wj, wy);
        ty = take.select(terms[j], ty);
        found |= take & pick.simd_lt(wj);
        pick -= wj;
    }
    let at = ((window + U::splat(POOL_STRIDE) * y) & U::splat(POOL_SLOTS - 1)) + lane;
    let field = |f: usize| gathered(at, f);
    let q = V3::new(field(0), field(1), field(2));
    let ny = V3::new(field(3), field(4), field(5));
    // `PooledLink`'s side and the loop's contribution of the picked candidate.
    let by = ny.dot(q - pos).simd_lt(zero);
    let cy = (beta_albedo * V3::new(field(9), field(10), field(11))).scale(ty);
    let target = offset_ray_origin(q, field(12), V3::select(by, ny, -ny));
    let open = unblocked(scene, p, spawn, target - spawn, go) & go;
    let added = cy.scale(sum / (F::splat(candidates as f32) * wy));
    *radiance = V3::select(open, *radiance + added, *radiance);
}

/// `crate::connection::pool_window` lane by lane.
#[inline(always)]
fn pool_windows(bits: U) -> U {
    (bits >> U::splat(32 - POOL_WINDOW_BITS)) * U::splat(POOL_STRIDE)
}
