//! The path loop of `crate::integrator` for sixteen samples in lockstep (a pixel's, or a few
//! neighbours' in a row): lane i follows its pixel's sample vertex by vertex, and a lane whose
//! path has ended stays masked off until the last one ends. Every step is the scalar integrator's for the variants `covers`
//! admits, in its order; the sampler's sets stay in step because every live path is at the same
//! vertex.
//!
//! With the wide BVH (the CPU path's traversal), the sixteen rays of a step in a small scene
//! are cast together against every triangle (`brute`); elsewhere the camera rays of a full
//! group are traced as one packet (`wide_packet`, which finds each ray's own hit): they leave
//! one pixel, or a few neighbours, in nearly one direction. The rays after them are traced one by one: from the first
//! vertex on, a pixel's rays are as incoherent as any, and packets of them were slower
//! (BENCHMARKS.md, "Packets of sixteen rays"). All three find the hit brute force finds, bit
//! for bit, so the image does not depend on which ran. A k-d traversal, asked for with
//! `--traversal`, traces every ray one by one: at extreme coordinates it may miss a hit within
//! rounding of a ray's origin that brute force finds (`tests/stress_renders.rs`), and the CPU
//! renders with it to compare with the GPU, which traverses the k-d tree.
use super::sampler::{LaneSampler, LaneSeeds};
use super::warp::{
    cosine_hemisphere, offset_ray_origin, orthonormal_basis, power_heuristic, power_heuristic3, primary_direction,
    uniform_triangle, weights, Triangles,
};
use super::{brute, split, sqrt, Hits, F, LANES, M, U, V3};
use crate::features::{
    Variant, FEATURES_ALL, FEATURE_DIFFUSE, FEATURE_EMITTERS, FEATURE_ENVIRONMENT, FEATURE_ENVIRONMENT_MAP,
    FEATURE_INDIRECT, FEATURE_MANY_EMITTERS, FEATURE_MATERIALS, FEATURE_PRINCIPLED, FEATURE_PUNCTUAL, FEATURE_TEXTURES,
    FEATURE_VERTEX_NORMALS,
};
use crate::glam::{Vec3, Vec4};
use crate::integrator::{has_lights, map_seen, medium_transmittance, PixelSpan, RR_MAX_SURVIVAL, SHADOW_EPSILON};
use crate::kdtree::Hit;
use crate::layout::{
    Material, RenderParams, AOV_RADIANCE, LIGHT_NOT_TRIANGLE, MATERIAL_DIFFUSE, NO_ENVIRONMENT_MAP, NO_HIT, NO_LIGHT,
    TRAVERSAL_WIDE_BVH,
};
use crate::light_sample::{other_light_sample, Shading};
use crate::material::{eval, is_delta, picks_lobe, sample as sample_bsdf, transmits};
use crate::numerics::sanitize;
use crate::raycast::query;
use crate::record::NoRecord;
use crate::rng::PixelSeeds;
use crate::sampling::{pick_light, INV_PI};
use crate::scene::SceneView;
use crate::surface::{emission_at, looks_up_textures, resolve, shading_normal};
use crate::vecmath::{dot, xyz};
use core::simd::cmp::{SimdPartialEq, SimdPartialOrd};
use core::simd::num::SimdFloat;
use core::simd::Select;

/// Whether a variant with feature bits `features` runs here: every feature does, given at
/// least one material kind. Texture lookups, alpha tests, shading normals, the BSDFs other than
/// Lambertian, the environment map and punctual lights run lane by lane, through the scalar
/// integrator's own functions (`surface`, `material`, `environment`,
/// `light_sample::other_light_sample`); the Lambertian BSDF and emitting triangles' light samples
/// run on all sixteen lanes at once.
#[inline(always)]
pub const fn covers(features: u32) -> bool {
    (features & !FEATURES_ALL == 0) & (features & FEATURE_MATERIALS != 0)
}

/// A group with fewer live lanes than this runs the scalar integrator: a group's cost hardly
/// falls with its live lanes, so one of four samples costs about what sixteen cost, more than
/// four samples one by one (BENCHMARKS.md, "The lane integrator"). Groups fill from several
/// pixels, so only the last group of a row (or of a row's few samples) can be short.
pub const MIN_LANES: usize = 8;

/// `integrator::render_pixels_for::<FEATURES>`, the same sums bit for bit: sixteen samples at
/// a time where `covers(FEATURES)` and the image is radiance, the scalar integrator otherwise.
/// The groups of sixteen lanes are filled from the row's samples in order, pixel by pixel and
/// within a pixel sample by sample, so a group holds one pixel's sixteen samples, two pixels'
/// eight (a pass of one block), sixteen pixels' one (a progressive or time-limited render's
/// first pass), or the end of one pixel's samples and the start of the next's (adaptive
/// sampling's uneven counts). Each lane's sample is added to its pixel's run's sums, in sample
/// order.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn render_pixels_for<const FEATURES: u32>(
    scene: &SceneView,
    p: &RenderParams,
    y: u32,
    pixels: &[PixelSpan],
    per: u32,
    runs: usize,
    sum: &mut [Vec4],
    sum_sq: &mut [Vec4],
    primary: &mut [u32],
) {
    if !covers(FEATURES) | (p.aov != AOV_RADIANCE) {
        crate::integrator::render_pixels_for::<FEATURES>(scene, p, y, pixels, per, runs, sum, sum_sq, primary);
        return;
    }
    let v = Variant::new(FEATURES, p);
    let (n, per) = (pixels.len(), per.max(1));
    // The next sample to place: pixel `k`, sample `s`; the seeds of the pixel placed last.
    let (mut k, mut s) = (0usize, pixels.first().map_or(0, |px| px.start));
    let mut seeds_of = usize::MAX;
    let mut seeds = PixelSeeds::new(p.sampler, 0, p.seed);
    let mut lane_seeds = LaneSeeds::splat(&seeds);
    loop {
        // Fill a group: lane `i` takes sample `sample[i]` of pixel `at[i]`. The seeds are set
        // lane by lane only in a group of several pixels (`mixed`), and splatted otherwise.
        let (mut at, mut sample, mut x) = ([0usize; LANES], [0u32; LANES], [0u32; LANES]);
        let (mut live, mut mixed) = (0, false);
        while (live < LANES) & (k < n) {
            let px = pixels[k];
            if s >= px.start + px.count {
                k += 1;
                s = pixels.get(k).map_or(0, |px| px.start);
                continue;
            }
            if seeds_of != k {
                if (live > 0) & !mixed {
                    // The lanes placed so far are all of the pixel before.
                    (lane_seeds, mixed) = (LaneSeeds::splat(&seeds), true);
                }
                (seeds_of, seeds) = (k, PixelSeeds::new(p.sampler, y * p.width + px.x, p.seed));
            }
            if mixed {
                lane_seeds.set_lane(live, &seeds);
            }
            (at[live], sample[live], x[live]) = (k, s, px.x);
            live += 1;
            s += 1;
        }
        if live == 0 {
            return;
        }
        if !mixed {
            lane_seeds = LaneSeeds::splat(&seeds);
        }
        let run_of = |i: usize| ((sample[i] - pixels[at[i]].start) / per) as usize * n + at[i];
        if live < MIN_LANES {
            // Sample by sample through the scalar integrator: the same sums in the same order.
            for i in 0..live {
                let (j, px) = (run_of(i), pixels[at[i]]);
                crate::integrator::render_samples(
                    scene,
                    p,
                    v,
                    px.x,
                    y,
                    sample[i],
                    1,
                    &mut sum[j],
                    &mut sum_sq[j],
                    &mut primary[at[i]],
                );
            }
            continue;
        }
        let mask = M::from_array(core::array::from_fn(|i| i < live));
        let pixel = U::from_array(x) + U::splat(y * p.width);
        let rng = LaneSampler::new(p.sampler, pixel, U::from_array(sample), p.seed, lane_seeds);
        let px = F::from_array(core::array::from_fn(|i| x[i] as f32));
        let (radiance, first) = trace_paths(scene, p, v, px, y, rng, mask);
        // Summed in lane order: each pixel's samples in sample order, as the scalar integrator
        // sums them.
        for i in 0..live {
            if sample[i] == 0 {
                primary[at[i]] = first[i];
            }
            let j = run_of(i);
            let (l, bad) = sanitize(radiance.lane(i), false);
            sum[j] += Vec4::new(l.x, l.y, l.z, if bad { 1.0 } else { 0.0 });
            sum_sq[j] += Vec4::new(l.x * l.x, l.y * l.y, l.z * l.z, 0.0);
        }
    }
}

/// Whether the live lanes' rays are cast by brute force (`brute`): in place of the wide BVH
/// (which finds the same hits bit for bit; a k-d traversal asked for by `--traversal` runs as
/// asked), in a scene without alpha masks whose triangles are few for the rays
/// (`brute::TRIANGLES_PER_RAY`).
#[inline(always)]
fn brute_force(scene: &SceneView, p: &RenderParams, live: M) -> bool {
    (p.traversal == TRAVERSAL_WIDE_BVH) & brute::pays(scene.triangles.len(), live) & !scene.alpha_masks
}

/// The closest hits of the live lanes' rays: by brute force in a small scene, through the split
/// (`split`) in a scene that has one, else one by one
/// by the chosen traversal, a camera ray group of sixteen as one packet.
#[inline(always)]
pub(super) fn trace_closest(scene: &SceneView, p: &RenderParams, origin: V3, dir: V3, live: M, packet: bool) -> Hits {
    if brute_force(scene, p, live) {
        return brute::cast(scene.triangles, &[], origin, dir, F::splat(f32::MAX), live, false);
    }
    if split::applies(scene, p, live) {
        return split::closest(scene, origin, dir, live);
    }
    let packet = packet & live.all() & (p.traversal == TRAVERSAL_WIDE_BVH);
    let (mut triangle, mut t, mut u, mut v, mut w) =
        ([NO_HIT; LANES], [0.0; LANES], [0.0; LANES], [0.0; LANES], [0.0; LANES]);
    let mut put =
        |i: usize, hit: Hit| (triangle[i], t[i], u[i], v[i], w[i]) = (hit.triangle, hit.t, hit.u, hit.v, hit.w);
    if packet {
        let o = core::array::from_fn(|i| origin.lane(i));
        let d = core::array::from_fn(|i| dir.lane(i));
        let hits = crate::wide_packet::traverse(scene, &o, &d, &[f32::MAX; LANES], LANES, false);
        for (i, hit) in hits.into_iter().enumerate() {
            put(i, hit);
        }
    } else {
        for i in 0..LANES {
            if live.test(i) {
                put(i, query(scene, p.traversal, origin.lane(i), dir.lane(i), f32::MAX, false).hit);
            }
        }
    }
    Hits {
        triangle: U::from_array(triangle),
        t: F::from_array(t),
        u: F::from_array(u),
        v: F::from_array(v),
        w: F::from_array(w),
    }
}

/// What a vertex needs of the triangles hit (or picked) by the live lanes: vertices, stored
/// normals, material albedo and emission (the material's constants; its index for texture
/// lookups), light-table entries.
pub(super) struct Gathered {
    pub(super) tris: Triangles,
    pub(super) albedo: V3,
    pub(super) emission: V3,
    pub(super) material: [u32; LANES],
    pub(super) light: [u32; LANES],
}

/// The lights that `u` picks, lane by lane as `sampling::pick_light` picks them: for each live
/// lane the light-table index, its triangle (or `LIGHT_NOT_TRIANGLE` kind), pmf and area, and
/// `u` rescaled within the picked light's interval. Lanes not live keep `u` and pick nothing.
pub(super) struct Picks {
    pub(super) index: [u32; LANES],
    pub(super) triangle: [u32; LANES],
    pub(super) pmf: F,
    pub(super) area: F,
    pub(super) u: F,
}

#[inline(always)]
pub(super) fn pick_lights(scene: &SceneView, many: bool, u: F, live: M) -> Picks {
    let (mut index, mut triangle) = ([0u32; LANES], [0u32; LANES]);
    let (mut pmf, mut area, mut u1) = ([0.0f32; LANES], [1.0f32; LANES], u.to_array());
    for i in 0..LANES {
        if live.test(i) {
            let (k, rescaled) = pick_light(scene.lights, scene.light_count, many, u1[i]);
            let light = scene.lights[k as usize];
            (index[i], u1[i]) = (k, rescaled);
            (triangle[i], pmf[i], area[i]) = (light.triangle, light.pmf, light.area);
        }
    }
    Picks { index, triangle, pmf: F::from_array(pmf), area: F::from_array(area), u: F::from_array(u1) }
}

/// Each live lane's point on its picked emitting triangle, `sampling::light_point` lane by lane,
/// with what the lanes need of that triangle (`gather`).
pub(super) struct LightPoints {
    pub(super) g: Gathered,
    pub(super) b: (F, F, F),
    pub(super) q: V3,
    pub(super) error: F,
    pub(super) n: V3,
}

#[inline(always)]
pub(super) fn light_points(scene: &SceneView, triangle: &[u32; LANES], live: M, u1: F, u2: F) -> LightPoints {
    let g = gather(scene, triangle, live);
    let b = uniform_triangle(u1, u2);
    let (q, error) = g.tris.interpolate(b.0, b.1, b.2);
    let n = g.tris.n;
    LightPoints { g, b, q, error, n }
}

#[inline(always)]
pub(super) fn gather(scene: &SceneView, triangle: &[u32; LANES], live: M) -> Gathered {
    // Rows of the sixteen lanes' values: v0, v1, v2 (x, y, z), the stored normal, albedo and
    // emission.
    let mut rows = [[0.0f32; LANES]; 18];
    let (mut material, mut light) = ([0; LANES], [NO_LIGHT; LANES]);
    for i in 0..LANES {
        if live.test(i) {
            let t = &scene.triangles[triangle[i] as usize];
            let info = scene.info[triangle[i] as usize];
            let m = &scene.materials[info.material as usize];
            let values = [
                t.v0.x,
                t.v0.y,
                t.v0.z,
                t.v1.x,
                t.v1.y,
                t.v1.z,
                t.v2.x,
                t.v2.y,
                t.v2.z,
                t.v0.w,
                t.v1.w,
                t.v2.w,
                m.albedo.x,
                m.albedo.y,
                m.albedo.z,
                m.emission.x,
                m.emission.y,
                m.emission.z,
            ];
            for (row, value) in rows.iter_mut().zip(values) {
                row[i] = value;
            }
            (material[i], light[i]) = (info.material, info.light);
        }
    }
    let v = |k: usize| V3::new(F::from_array(rows[k]), F::from_array(rows[k + 1]), F::from_array(rows[k + 2]));
    Gathered {
        tris: Triangles { v0: v(0), v1: v(3), v2: v(6), n: v(9) },
        albedo: v(12),
        emission: v(15),
        material,
        light,
    }
}

/// `integrator::trace_path` for the live lanes' samples, lane i's of pixel (px[i], py): their
/// radiance, and the triangle each camera ray hit first.
#[inline(always)]
fn trace_paths(
    scene: &SceneView,
    p: &RenderParams,
    v: Variant,
    px: F,
    py: u32,
    mut rng: LaneSampler,
    live: M,
) -> (V3, [u32; LANES]) {
    let zero = F::splat(0.0);
    let (jx, jy) = rng.next_2d();
    let mut origin = V3::splat(xyz(p.eye));
    let mut dir = primary_direction(p, px + jx, F::splat(py as f32) + jy);
    let mut beta = V3::splat(Vec3::ONE);
    let mut radiance = V3::ZERO;
    let mut bsdf_pdf = zero;
    let mut bounce = 0u32;
    let mut first = [NO_HIT; LANES];
    // Whether some lanes shade through the scalar integrator's functions (`Kinds`): material
    // kinds other than Lambertian, the environment map's and punctual lights' samples.
    let kinds = !v.only_material(FEATURE_DIFFUSE) | v.has(FEATURE_ENVIRONMENT_MAP) | v.has(FEATURE_PUNCTUAL);
    let mut alive = live;
    let lights = has_lights(scene, v);
    let many = v.has(FEATURE_MANY_EMITTERS);
    let bidir = crate::connection::connects(scene, p, v);
    let kappa = crate::connection::connection_weight(p);
    let lv = if bidir & (p.light_pool == 0) {
        super::connection::light_vertices(scene, p, many, &rng, live)
    } else {
        super::connection::LightVertex::none()
    };
    // The previous vertex's 1 / (pi * its area density from the vertex before), 0 where the
    // connection strategy cannot make the path; and |n . wi| there.
    let (mut prev_inv_pi_a, mut prev_cos) = (zero, zero);
    while alive.any() {
        let hits = trace_closest(scene, p, origin, dir, alive, bounce == 0);
        if bounce == 0 {
            first = hits.triangle.to_array();
        }
        let hit = hits.triangle.simd_ne(U::splat(NO_HIT)) & alive;
        let escaped = alive & !hit;
        if v.has(FEATURE_ENVIRONMENT_MAP) & (p.environment_map != NO_ENVIRONMENT_MAP) {
            // The map, MIS-weighted against its light samples (`trace_path`), lane by lane.
            for i in 0..LANES {
                if escaped.test(i) {
                    let (le, weight) = map_seen(scene, p.environment_map - 1, dir.lane(i), bounce, bsdf_pdf[i]);
                    let sum = radiance.lane(i) + beta.lane(i) * le * weight;
                    (radiance.x[i], radiance.y[i], radiance.z[i]) = (sum.x, sum.y, sum.z);
                }
            }
        } else if v.has(FEATURE_ENVIRONMENT) & escaped.any() {
            radiance = V3::select(escaped, radiance + beta * V3::splat(xyz(p.environment)), radiance);
        }
        alive = hit;
        if !alive.any() {
            break;
        }

        // `shade_vertex`: the sets first, in the scalar order.
        let last = !v.has(FEATURE_INDIRECT) | (bounce == v.max_bounces + 1);
        let (u_select, u_light) = if lights & !last { rng.next_2d() } else { (zero, zero) };
        let [ub1, ub2, u_roulette] = if last { [zero; 3] } else { rng.next_3d() };
        let triangles = hits.triangle.to_array();
        let mut g = gather(scene, &triangles, alive);
        // The hit's barycentric weights, for its point, textures and vertex normals.
        let b = weights(hits.u, hits.v, hits.w);
        // Where some lanes shade through the scalar functions (`kinds`), the materials with
        // their textures looked up, for `Kinds`; other variants keep none.
        let mut resolved = [Material::default(); LANES];
        let mut textured = [false; LANES];
        if v.has(FEATURE_TEXTURES) & !scene.textures.is_empty() {
            // `surface::resolve`, lane by lane: the texels at the hit replace the constants.
            for (i, &tri) in triangles.iter().enumerate() {
                if !alive.test(i) {
                    continue;
                }
                let base = &scene.materials[g.material[i] as usize];
                if looks_up_textures(scene, v, base) {
                    let r = resolve(scene, v, base, tri, (b.0[i], b.1[i], b.2[i]));
                    (g.albedo.x[i], g.albedo.y[i], g.albedo.z[i]) = (r.albedo.x, r.albedo.y, r.albedo.z);
                    (g.emission.x[i], g.emission.y[i], g.emission.z[i]) = (r.emission.x, r.emission.y, r.emission.z);
                    if kinds {
                        (resolved[i], textured[i]) = (r, true);
                    }
                }
            }
        }
        let t = hits.t;
        let ng = g.tris.geometric_normal();
        let n = g.tris.n;
        let (pos, error) = g.tris.interpolate(b.0, b.1, b.2);
        let front = ng.dot(dir).simd_lt(zero);
        let wo = -dir.normalize();
        let k = if kinds {
            let mats: [&Material; LANES] = core::array::from_fn(|i| {
                if textured[i] | !alive.test(i) {
                    &resolved[i]
                } else {
                    &scene.materials[g.material[i] as usize]
                }
            });
            Some(Kinds::new(v, mats, alive, wo, front))
        } else {
            None
        };
        // A ray that reaches a surface from behind travelled inside it: an absorbing medium
        // takes its share (`shade_vertex`), lane by lane.
        if let (Some(k), true) = (&k, v.has(FEATURE_PRINCIPLED)) {
            for i in 0..LANES {
                if !alive.test(i) {
                    continue;
                }
                let keep = medium_transmittance(v, k.mats[i], ng.lane(i), dir.lane(i), t[i]);
                (beta.x[i], beta.y[i], beta.z[i]) = (beta.x[i] * keep.x, beta.y[i] * keep.y, beta.z[i] * keep.z);
            }
        }

        if v.has(FEATURE_EMITTERS) {
            let le = V3::select(front, g.emission, V3::ZERO);
            let emits = le.any_positive() & alive;
            if emits.any() {
                let mut weight = F::splat(1.0);
                if bounce > 0 {
                    let (mut pmf, mut area, mut entry) = ([1.0f32; LANES], [1.0f32; LANES], [false; LANES]);
                    for i in 0..LANES {
                        if emits.test(i) & (g.light[i] != NO_LIGHT) {
                            let l = scene.lights[g.light[i] as usize];
                            (pmf[i], area[i], entry[i]) = (l.pmf, l.area, true);
                        }
                    }
                    let dist2 = t * t * dir.dot(dir);
                    let cos_l = n.dot(dir.normalize()).abs();
                    let light_pdf = F::from_array(pmf) * dist2 / (cos_l * F::from_array(area));
                    let w = if bidir {
                        let q2 = F::from_array(pmf) / F::from_array(area) * prev_cos * prev_inv_pi_a * F::splat(kappa);
                        power_heuristic3(bsdf_pdf, light_pdf, q2)
                    } else {
                        power_heuristic(bsdf_pdf, light_pdf)
                    };
                    weight = M::from_array(entry).select(w, weight);
                }
                radiance = V3::select(emits, radiance + (beta * le).scale(weight), radiance);
            }
        }
        if last {
            break;
        }

        let nf = V3::select(front, n, -n);
        let spawn = offset_ray_origin(pos, error, nf);
        // `surface::shading_normal`, lane by lane where there are vertex normals; the flat
        // normal otherwise.
        let ns = if v.has(FEATURE_VERTEX_NORMALS) & !scene.attributes.is_empty() {
            let mut ns = [Vec3::ZERO; LANES];
            for (i, n) in ns.iter_mut().enumerate() {
                if alive.test(i) {
                    *n = shading_normal(scene, v, triangles[i], (b.0[i], b.1[i], b.2[i]), nf.lane(i), wo.lane(i));
                }
            }
            V3::from_lanes(&ns)
        } else {
            nf
        };
        let sides = Sides { check: v.has(FEATURE_VERTEX_NORMALS), nf, ns };
        // This vertex's area density from the vertex before (BSDF-sampled there), for the
        // connection strategy's MIS weight.
        let inv_pi_a = if bidir & (bounce > 0) {
            let len2 = dir.dot(dir);
            sqrt(len2) * len2 * t * t / (prev_cos * n.dot(dir).abs())
        } else {
            zero
        };
        if lights {
            let nee = k.as_ref().map_or(alive, |k| alive & !k.delta);
            let bsdfs = k.as_ref();
            next_event(
                scene,
                p,
                v,
                many,
                &g,
                bsdfs,
                nee,
                pos,
                error,
                spawn,
                sides,
                beta,
                u_select,
                u_light,
                bidir,
                inv_pi_a,
                &mut radiance,
            );
        }
        if bidir & (bounce < v.max_bounces) {
            if p.light_pool != 0 {
                let c = (pos, spawn, nf, g.albedo, beta);
                super::connection::connect_pooled(
                    scene,
                    p,
                    &rng,
                    bounce,
                    alive,
                    c.0,
                    c.1,
                    c.2,
                    c.3,
                    c.4,
                    &mut radiance,
                );
            } else {
                super::connection::connect(scene, p, &lv, alive, pos, spawn, nf, g.albedo, beta, &mut radiance);
            }
        }

        // The Lambertian BSDF sample (`material::diffuse::sample`) on every lane; no lobe to
        // pick.
        let local = cosine_hemisphere(ub1, ub2);
        let (tb, bb) = orthonormal_basis(ns);
        let mut wi = tb.scale(local.x) + bb.scale(local.y) + ns.scale(local.z);
        let mut pdf = local.z * F::splat(INV_PI);
        let mut weight = g.albedo;
        // The lanes whose next ray leaves from the far side (refracted).
        let mut through = M::splat(false);
        if let Some(k) = &k {
            // The other kinds' samples, lane by lane (`material::sample`), the lobe picked by
            // the uniform the scalar integrator draws (`independent_after`).
            let todo = alive & k.other;
            if todo.any() {
                let u_pick = rng.independent_after();
                for i in 0..LANES {
                    if !todo.test(i) {
                        continue;
                    }
                    let m = k.mats[i];
                    let u3 = if picks_lobe(v, m) { u_pick[i] } else { 0.0 };
                    let bs =
                        sample_bsdf(v, m, scene.textures, ns.lane(i), wo.lane(i), front.test(i), ub1[i], ub2[i], u3);
                    (wi.x[i], wi.y[i], wi.z[i], pdf[i]) = (bs.wi.x, bs.wi.y, bs.wi.z, bs.pdf);
                    (weight.x[i], weight.y[i], weight.z[i]) = (bs.weight.x, bs.weight.y, bs.weight.z);
                    through.set(i, transmits(v, m) & (dot(bs.wi, nf.lane(i)) < 0.0));
                }
            }
        }
        alive &= !pdf.simd_le(zero) & sides.consistent(wi);
        if bidir {
            (prev_inv_pi_a, prev_cos) = (inv_pi_a, nf.dot(wi).abs());
        }
        beta = V3::select(alive, beta * weight, beta);
        bsdf_pdf = pdf;
        bounce += 1;
        if bounce >= v.rr_start {
            let survive = beta.x.simd_max(beta.y).simd_max(beta.z).simd_min(F::splat(RR_MAX_SURVIVAL));
            alive &= !u_roulette.simd_ge(survive);
            beta = beta.divide(survive);
        }
        origin = if through.any() { V3::select(through, offset_ray_origin(pos, error, -nf), spawn) } else { spawn };
        dir = wi;
    }
    (radiance, first)
}

/// A vertex's flat normal `nf` (toward the side the ray came from) and shading normal `ns`.
#[derive(Clone, Copy)]
struct Sides {
    /// Whether the variant has vertex normals, so that the two may differ.
    check: bool,
    nf: V3,
    ns: V3,
}

impl Sides {
    /// `surface::consistent`, lane by lane: whether `wi` lies on the same side of both normals.
    #[inline(always)]
    fn consistent(&self, wi: V3) -> M {
        let zero = F::splat(0.0);
        if self.check {
            !(self.nf.dot(wi).simd_gt(zero) ^ self.ns.dot(wi).simd_gt(zero))
        } else {
            M::splat(true)
        }
    }
}

/// The live lanes' materials where some lanes shade through the scalar integrator's functions
/// (material kinds other than Lambertian, the environment map, punctual lights): the material
/// each lane's BSDF sees (its textures looked up), the lanes whose kind is not Lambertian (their
/// BSDFs run lane by lane through `material`, the Lambertian lanes on all lanes at once), and
/// those whose every lobe is a delta (no light sample), with the vertex's `wo` and sides.
struct Kinds<'a> {
    mats: [&'a Material; LANES],
    other: M,
    delta: M,
    wo: V3,
    front: M,
}

impl<'a> Kinds<'a> {
    #[inline(always)]
    fn new(v: Variant, mats: [&'a Material; LANES], alive: M, wo: V3, front: M) -> Self {
        let other = M::from_array(core::array::from_fn(|i| mats[i].kind != MATERIAL_DIFFUSE)) & alive;
        let delta = M::from_array(core::array::from_fn(|i| is_delta(v, mats[i]))) & alive;
        Kinds { mats, other, delta, wo, front }
    }
}

/// Next-event estimation (`shade_vertex`'s light sample) for the live lanes: a light picked per
/// lane; on an emitting triangle a point on it, the shadow rays one by one (or by brute force),
/// the unblocked lanes' MIS-weighted contributions added to `radiance`, each lane's BSDF value
/// from `kinds` where its kind is not Lambertian; the environment map and punctual lights lane
/// by lane (`light_sample::other_light_sample`, given `kinds`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn next_event(
    scene: &SceneView,
    p: &RenderParams,
    v: Variant,
    many: bool,
    g: &Gathered,
    kinds: Option<&Kinds>,
    alive: M,
    pos: V3,
    error: F,
    spawn: V3,
    sides: Sides,
    beta: V3,
    u_select: F,
    u_light: F,
    bidir: bool,
    inv_pi_a: F,
    radiance: &mut V3,
) {
    let zero = F::splat(0.0);
    let (nf, ns) = (sides.nf, sides.ns);
    let picks = pick_lights(scene, many, u_select, alive);
    let (pmf, area) = (picks.pmf, picks.area);
    let mut on_triangle = alive;
    if let (Some(k), true) = (kinds, v.has(FEATURE_ENVIRONMENT_MAP) | v.has(FEATURE_PUNCTUAL)) {
        for i in 0..LANES {
            if alive.test(i) & (picks.triangle[i] >= LIGHT_NOT_TRIANGLE) {
                // The environment map or a punctual light: the scalar integrator's sample.
                on_triangle.set(i, false);
                let mut sum = radiance.lane(i);
                let s = other_light_sample(
                    scene,
                    v,
                    beta.lane(i),
                    k.mats[i],
                    picks.triangle[i],
                    pmf[i],
                    picks.index[i],
                    &Shading {
                        pos: pos.lane(i),
                        spawn: spawn.lane(i),
                        error: Vec3::splat(error[i]),
                        nf: nf.lane(i),
                        ns: ns.lane(i),
                        wo: k.wo.lane(i),
                        front: k.front.test(i),
                    },
                    picks.u[i],
                    u_light[i],
                );
                let open = s.ray.open(scene, p, &mut NoRecord);
                s.finish(open, &mut sum, &mut NoRecord);
                (radiance.x[i], radiance.y[i], radiance.z[i]) = (sum.x, sum.y, sum.z);
            }
        }
    }
    let alive = on_triangle;
    if !alive.any() {
        return;
    }
    let LightPoints { g: mut lg, b: (b0, b1, b2), q, error: q_error, n: nl } =
        light_points(scene, &picks.triangle, alive, picks.u, u_light);
    if v.has(FEATURE_TEXTURES) & !scene.textures.is_empty() {
        // `surface::emission_at`: an emission texture at the point picked.
        for i in 0..LANES {
            if alive.test(i) {
                let m = &scene.materials[lg.material[i] as usize];
                let e = emission_at(scene, v, m, picks.triangle[i], (b0[i], b1[i], b2[i]));
                (lg.emission.x[i], lg.emission.y[i], lg.emission.z[i]) = (e.x, e.y, e.z);
            }
        }
    }
    let to_light = q - pos;
    let dist2 = to_light.dot(to_light);
    let wi = to_light.scale(F::splat(1.0) / sqrt(dist2));
    let cos_l = -nl.dot(wi);
    // The Lambertian BSDF's value and density (`material::diffuse::eval`).
    let cos_i = ns.dot(wi);
    let mut pdf_bsdf = cos_i.simd_gt(zero).select(cos_i * F::splat(INV_PI), zero);
    let mut f = g.albedo.scale(F::splat(INV_PI));
    if let Some(k) = kinds {
        // The other kinds' values and densities, lane by lane (`material::eval`).
        let todo = alive & k.other;
        for i in 0..LANES {
            if todo.test(i) {
                let (fi, pi) =
                    eval(v, k.mats[i], scene.textures, ns.lane(i), k.wo.lane(i), wi.lane(i), k.front.test(i));
                (f.x[i], f.y[i], f.z[i], pdf_bsdf[i]) = (fi.x, fi.y, fi.z, pi);
            }
        }
    }
    let valid = alive & cos_l.simd_gt(zero) & pdf_bsdf.simd_gt(zero) & dist2.simd_gt(zero) & sides.consistent(wi);
    if !valid.any() {
        return;
    }
    let light_pdf = pmf * dist2 / (cos_l * area);
    let target = offset_ray_origin(q, q_error, nl);
    let behind = nf.dot(wi).simd_lt(zero);
    let from =
        if (behind & valid).any() { V3::select(behind, offset_ray_origin(pos, error, -nf), spawn) } else { spawn };
    let shadow_dir = target - from;
    let unblocked = unblocked(scene, p, from, shadow_dir, valid);
    let weight = if bidir {
        let q2 = pmf / area * nf.dot(wi).abs() * inv_pi_a * F::splat(crate::connection::connection_weight(p));
        power_heuristic3(light_pdf, pdf_bsdf, q2)
    } else {
        power_heuristic(light_pdf, pdf_bsdf)
    };
    let added = (beta * f * lg.emission).scale(cos_i.abs() * weight / light_pdf);
    *radiance = V3::select(unblocked, *radiance + added, *radiance);
}

/// Whether the live lanes' segments `from` to `from + dir` (to 1 - SHADOW_EPSILON of it) are
/// unblocked.
#[inline(always)]
pub(super) fn unblocked(scene: &SceneView, p: &RenderParams, from: V3, dir: V3, valid: M) -> M {
    (if brute_force(scene, p, valid) {
        let t_max = F::splat(1.0 - SHADOW_EPSILON);
        brute::cast(scene.triangles, &[], from, dir, t_max, valid, true).triangle.simd_eq(U::splat(NO_HIT))
    } else if split::applies(scene, p, valid) {
        split::unblocked(scene, from, dir, F::splat(1.0 - SHADOW_EPSILON), valid)
    } else {
        let mut unblocked = [false; LANES];
        for (i, u) in unblocked.iter_mut().enumerate() {
            if valid.test(i) {
                *u = !query(scene, p.traversal, from.lane(i), dir.lane(i), 1.0 - SHADOW_EPSILON, true).hit.is_hit();
            }
        }
        M::from_array(unblocked)
    }) & valid
}
