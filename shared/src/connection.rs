//! Light subpaths connected to the eye vertices: a third way of making a path besides the path
//! tracer's BSDF sampling and next-event estimation, for light that reaches the camera after two
//! or more diffuse bounces (Veach 1997, ch. 10, the bidirectional estimator with a light subpath
//! of one segment; Veach & Guibas 1995 for the weights).
//!
//! Each camera sample traces one light subpath: a point on an emitting triangle, picked as
//! next-event estimation picks it, and a cosine-distributed direction to the first surface it
//! reaches, `y`. Every eye vertex below the bounce limit joins `y` with a shadow ray. The power
//! heuristic weighs the three strategies that can make a path through `y` and the light: the
//! density of each is a product over the path's last two segments, so the integrator's
//! emitter-hit and light-sample weights take the third density from `inv_pi_area` of the eye
//! vertex before, and the three weights of a path sum to one.
//!
//! With the light pool (`RenderParams::light_pool`, the default) the light subpaths are not the
//! sample's own but drawn from a pool that all pixels share (`LightPool`): `POOL_SLOTS` of
//! them are traced for every block of `POOL_SAMPLES` samples before those samples run (on the
//! CPU by the host, on a GPU by the `trace_pool` entry point, both through `pool_record`),
//! and each eye vertex weighs up to `POOL_CANDIDATES` of them (`pool_candidates`, fewer at
//! deeper vertices) from a random window by their
//! unshadowed contributions, picks one in proportion and traces one shadow ray to it
//! (resampled importance sampling: Talbot et al. 2005; the pool of light vertices: Davidovič et
//! al. 2014, "Progressive light transport simulation on the GPU", the light vertex cache). The
//! estimate is unbiased whatever the weights, and costs one shadow ray as before, but an eye
//! vertex in a gallery now connects to the floor points that light it most. As the strategy is
//! better than one connection, its density in the three strategies' weights is counted
//! `POOL_WEIGHT` times (any factor keeps the weights summing to one).
//!
//! The pool is stored field by field (`POOL_FIELDS` rows of `POOL_SLOTS` floats a block,
//! `pool_index`), and the `POOL_STRIDE` samples of a pixel that the CPU's lane integrator runs
//! together share one window of `POOL_STRIDE * POOL_CANDIDATES` slots (`pool_window`, hashed
//! from the pixel, their group and the bounce): sample `s`'s candidate `j` is slot
//! `window + POOL_STRIDE * j + s % POOL_STRIDE`. The samples' candidates are distinct, and
//! sixteen lanes read a field of their candidates `j` from consecutive floats rather than by a
//! gather.
//!
//! It serves scenes where `features::connection_applies`: Lambertian vertices at both ends (the
//! BSDF is albedo / pi), flat normals, emitting triangles. `RenderParams::connect` switches it on
//! and `FEATURE_CONNECT` compiles it; the lane integrator runs the same estimator sixteen samples
//! at a time (`lanes::integrator`).
use crate::features::{Variant, FEATURES_ALL, FEATURE_CONNECT, FEATURE_MANY_EMITTERS};
use crate::glam::Vec3;
use crate::kdtree::Hit;
use crate::layout::{RenderParams, AOV_RADIANCE, LIGHT_NOT_TRIANGLE};
use crate::numerics::offset_ray_origin;
use crate::raycast::{closest, query_recorded};
use crate::record::NoRecord;
use crate::rng::Sampler;
use crate::sampling::{cosine_hemisphere, light_point, orthonormal_basis, pick_light, power_heuristic3, INV_PI};
use crate::scene::SceneView;
use crate::shadow::ShadowRay;
use crate::triangle::{hit_point, stored_normal, TriangleHit};
use crate::vecmath::{dot, length_squared, xyz};
#[allow(unused_imports)]
use spirv_std::num_traits::Float;

/// The hash key of the light subpath's uniforms (`Sampler::independent_4d`).
pub const CONNECT_TAG: u32 = 0xB1D1_0001;
/// The hash key (plus the bounce) of a pooled connection's pick among its candidates.
pub const POOL_PICK_TAG: u32 = 0xB1D1_0100;
/// The hash key (plus the bounce) of the window a group of `POOL_STRIDE` samples draws its
/// candidates from (`Sampler::group_bits`).
pub const POOL_WINDOW_TAG: u32 = 0xB1D1_0200;
/// Samples of a pixel that share a window of candidates, each taking every `POOL_STRIDE`th slot
/// of it: the lane integrator's sixteen (`lanes::LANES`).
pub const POOL_STRIDE: u32 = 16;
/// Samples of a pixel that draw from one pool of light subpaths: sample `s` from block
/// `s / POOL_SAMPLES`'s.
pub const POOL_SAMPLES: u32 = 8;
/// Light subpaths in a block's pool (a power of two).
pub const POOL_SLOTS: u32 = 4096;
/// Light vertices an eye vertex weighs before it picks one, at most (`pool_candidates`): the
/// rows of a window.
pub const POOL_CANDIDATES: usize = 32;
/// The factor on the pooled connection's density in the multiple-importance weights.
pub const POOL_WEIGHT: f32 = 16.0;
/// Fields of a pooled light vertex (`LightVertex::record`): position, stored normal, the normal's
/// cosine to the light point, the two terms of its weights (`PooledLink`), albedo times power,
/// rounding error.
pub const POOL_FIELDS: usize = 13;
/// Floats of a block's pool: `POOL_FIELDS` rows of `POOL_SLOTS`.
pub const POOL_BLOCK: usize = POOL_FIELDS * POOL_SLOTS as usize;
/// Seeds the pool's hash apart from the pixels' samplers.
const POOL_SEED: u32 = 0x7f4a_7c15;
/// Bits of a window's index in its block (`pool_window`).
pub const POOL_WINDOW_BITS: u32 = (POOL_SLOTS / POOL_STRIDE).trailing_zeros();

/// The light subpaths of blocks `first_block ..` (`POOL_BLOCK` floats a block, `pool_index`),
/// shared by every pixel's samples in those blocks.
#[derive(Clone, Copy)]
#[cfg_attr(not(target_arch = "spirv"), derive(Default))]
pub struct LightPool<'a> {
    pub records: &'a [f32],
    pub first_block: u32,
}

impl LightPool<'_> {
    /// Where the records of sample `sample`'s block start in `records`.
    #[inline(always)]
    pub fn offset(&self, sample: u32) -> usize {
        (sample / POOL_SAMPLES - self.first_block) as usize * POOL_BLOCK
    }
}

/// Where field `field` of slot `slot` of the `block`th block of a pool buffer is.
#[inline(always)]
pub fn pool_index(block: usize, field: usize, slot: usize) -> usize {
    block * POOL_BLOCK + field * POOL_SLOTS as usize + slot
}

/// The factor on the connection strategy's density in the weights: `POOL_WEIGHT` for the pooled
/// connections, 1 for the sample's own light subpath.
#[inline(always)]
pub fn connection_weight(p: &RenderParams) -> f32 {
    if p.light_pool != 0 {
        POOL_WEIGHT
    } else {
        1.0
    }
}

/// Slot `slot` of block `block`'s pool: a light subpath as `light_vertex` traces one, from
/// uniforms hashed from the block, the slot and the seed. Traced with the generic variant,
/// whichever variant renders: the pool is the same for every variant of a render.
pub fn pool_record(scene: &SceneView, p: &RenderParams, block: u32, slot: u32) -> [f32; POOL_FIELDS] {
    let rng = Sampler::new(crate::rng::SAMPLER_INDEPENDENT, slot, block, p.seed ^ POOL_SEED);
    light_vertex(scene, p, Variant::new(FEATURES_ALL, p), &rng).record()
}

/// The record of light subpath `index` of a pool buffer whose first block is
/// `p.pool_first_block`: slot `index % POOL_SLOTS` of the `index / POOL_SLOTS`th block
/// (`pool_record`).
#[inline(always)]
pub fn pool_buffer_record(scene: &SceneView, p: &RenderParams, index: u32) -> [f32; POOL_FIELDS] {
    let (block, slot) = pool_block_slot(index);
    pool_record(scene, p, p.pool_first_block + block, slot)
}

/// The block (counted from the buffer's first) and the slot of light subpath `index` of a pool
/// buffer.
#[inline(always)]
fn pool_block_slot(index: u32) -> (u32, u32) {
    (index / POOL_SLOTS, index % POOL_SLOTS)
}

/// Stores record `r` of light subpath `index` (`pool_buffer_record`) field by field in `pool`.
#[inline(always)]
pub fn store_pool_record(pool: &mut [f32], index: u32, r: &[f32; POOL_FIELDS]) {
    let (block, slot) = pool_block_slot(index);
    let mut f = 0;
    while f < POOL_FIELDS {
        pool[pool_index(block as usize, f, slot as usize)] = r[f];
        f += 1;
    }
}

/// Whether the connection strategy runs for variant `v` with `p`: compiled in (`FEATURE_CONNECT`),
/// asked for (`RenderParams::connect`, which the host sets only where the scene's features allow
/// it), the radiance image, a light to start from and a bounce to connect.
#[inline(always)]
pub fn connects(scene: &SceneView, p: &RenderParams, v: Variant) -> bool {
    v.has(FEATURE_CONNECT) & (p.connect != 0) & (p.aov == AOV_RADIANCE) & (scene.light_count > 0) & (v.max_bounces > 0)
}

/// 1 / (pi * the area density at a vertex reached from a Lambertian vertex by a cosine-sampled
/// direction `dir` (any length) at parameter `t`, `prev_cos` the cosine there, `n` the normal
/// reached): times the light point's area density and the cosine there, the density of the
/// connection strategy making the path (the connection's Lambertian pdf at the vertex is
/// |cos| / pi). The sample's density prev_cos / pi times |cos| / dist² is the area density,
/// so pi cancels. Written without the constant, the kernel computes what the CPU does: the
/// SPIR-V optimiser rewrites `1 / (pi * x)` as `(1 / pi) / x`, which rounds differently.
#[inline(always)]
pub fn inv_pi_area(prev_cos: f32, n: Vec3, dir: Vec3, t: f32) -> f32 {
    let len2 = length_squared(dir);
    len2.sqrt() * len2 * t * t / (prev_cos * dot(n, dir).abs())
}

/// Whether the camera ray through image point (`x`, `y`) sees, from its first hit, a point
/// sampled on an emitting triangle as next-event estimation samples it (light and point from
/// `u0`, `u1`): `None` where the ray leaves the scene, the light picked is not a triangle or
/// the hit and the point do not face each other. The host's `Connect::Auto` counts these over a
/// grid of the image (`render::features::seen_light_share`).
pub fn first_hit_sees_light(scene: &SceneView, p: &RenderParams, x: f32, y: f32, u0: f32, u1: f32) -> Option<bool> {
    let dir = crate::camera::primary_direction(p, x, y);
    let hit = closest(scene, p.traversal, xyz(p.eye), dir, f32::MAX).hit;
    if !hit.is_hit() {
        return None;
    }
    let tri = &scene.triangles[hit.triangle as usize];
    let at = hit_point(tri, &TriangleHit { t: hit.t, u: hit.u, v: hit.v, w: hit.w });
    let n = stored_normal(tri);
    let nf = if dot(n, dir) < 0.0 { n } else { -n };
    let (index, u0) = pick_light(scene.lights, scene.light_count, scene.light_count > 1, u0);
    let light = scene.lights[index as usize];
    if light.triangle >= LIGHT_NOT_TRIANGLE {
        return None;
    }
    let lp = light_point(&scene.triangles[light.triangle as usize], u0, u1);
    let (on_light, nl) = (lp.at, lp.n);
    let to_light = on_light.p - at.p;
    // Emitters emit on the side of their stored normal (`surface::emitted`).
    if !(dot(nf, to_light) > 0.0) | !(dot(nl, to_light) < 0.0) {
        return None;
    }
    let from = offset_ray_origin(at.p, at.error, nf);
    // The side the point sees: the emitting one, by the test above.
    let target = offset_ray_origin(on_light.p, on_light.error, nl);
    Some(ShadowRay::toward(from, target).open(scene, p, &mut NoRecord))
}

/// The first vertex of a light subpath: a point on an emitting triangle (picked as next-event
/// estimation picks it), a cosine-distributed direction, the surface it reaches.
// `repr(C)`: in Rust's own order the fields' offsets need not rise with their index in the
// SPIR-V struct, which naga rejects ("overlaps the previous member").
#[repr(C)]
#[derive(Clone, Copy)]
pub struct LightVertex {
    pos: Vec3,
    error: Vec3,
    /// The stored unit normal of the triangle reached.
    n: Vec3,
    albedo: Vec3,
    /// Unit direction from the vertex to the point on the light.
    to_light: Vec3,
    dist2: f32,
    cos_l: f32,
    /// The light point's area density (pmf / area).
    pa: f32,
    /// Emission / (pi pa): the subpath's weight at the vertex (emission * pi / pa) times the
    /// 1 / pi² of the two Lambertian BSDFs a connection evaluates (their albedos apart);
    /// `INV_PI / pa`, the form the SPIR-V optimiser leaves as it is.
    power: Vec3,
    valid: bool,
}

impl LightVertex {
    /// The vertex as a pool record (`POOL_FIELDS`); zeros, which no eye vertex picks, where it
    /// is not valid.
    pub fn record(&self) -> [f32; POOL_FIELDS] {
        if !self.valid {
            return [0.0; POOL_FIELDS];
        }
        let (y, n, w) = (self.pos, self.n, self.albedo * self.power);
        let (cos, q1) = (dot(n, self.to_light), self.q1());
        let q0 = cos * INV_PI;
        [
            y.x,
            y.y,
            y.z,
            n.x,
            n.y,
            n.z,
            cos,
            1.0 / (POOL_WEIGHT * self.pa * cos.abs()),
            q0 * q0 + q1 * q1,
            w.x,
            w.y,
            w.z,
            self.error.x,
        ]
    }

    /// The light subpath's density at its vertex: the light point's area density times the
    /// area density of its cosine-sampled direction there.
    #[inline(always)]
    fn q1(&self) -> f32 {
        self.pa * self.dist2 / self.cos_l
    }

    pub const NONE: LightVertex = LightVertex {
        pos: Vec3::ZERO,
        error: Vec3::ZERO,
        n: Vec3::ZERO,
        albedo: Vec3::ZERO,
        to_light: Vec3::ZERO,
        dist2: 0.0,
        cos_l: 0.0,
        pa: 0.0,
        power: Vec3::ZERO,
        valid: false,
    };
}

/// Traces the light subpath of the sampler's sample (its uniforms keyed by `CONNECT_TAG`).
#[inline(always)]
pub fn light_vertex(scene: &SceneView, p: &RenderParams, v: Variant, rng: &Sampler) -> LightVertex {
    let ray = light_ray(scene, v, rng);
    if !ray.ok {
        return LightVertex::NONE;
    }
    ray.vertex(scene, &query_recorded(scene, p.traversal, ray.origin, ray.dir, f32::MAX, false, &mut NoRecord).hit)
}

/// The first ray of a light subpath, prepared (`light_ray`), and what its vertex takes from the
/// light (`LightRay::vertex`): the integrator traces it with the path's own query, so that a
/// shader holds one copy of the traversal for both.
#[derive(Clone, Copy)]
pub struct LightRay {
    /// There is a ray to trace: a triangle light emitting, the direction above it.
    pub ok: bool,
    pub origin: Vec3,
    pub dir: Vec3,
    /// The direction's cosine to the light's normal.
    cos_l: f32,
    /// The light point's area density: the light's pick probability over its area.
    pa: f32,
    /// The light's emitted radiance.
    le: Vec3,
}

impl LightRay {
    pub const NONE: LightRay =
        LightRay { ok: false, origin: Vec3::ZERO, dir: Vec3::Z, cos_l: 0.0, pa: 0.0, le: Vec3::ZERO };

    /// The light vertex where the ray hit (`hit`, `NO_HIT` for none).
    #[inline(always)]
    pub fn vertex(&self, scene: &SceneView, hit: &Hit) -> LightVertex {
        if !self.ok | !hit.is_hit() {
            return LightVertex::NONE;
        }
        let tri = &scene.triangles[hit.triangle as usize];
        let m = &scene.materials[scene.info[hit.triangle as usize].material as usize];
        let albedo = Vec3::new(m.albedo.x, m.albedo.y, m.albedo.z);
        let surface = hit_point(tri, &TriangleHit { t: hit.t, u: hit.u, v: hit.v, w: hit.w });
        let len2 = length_squared(self.dir);
        LightVertex {
            valid: (albedo.x > 0.0) | (albedo.y > 0.0) | (albedo.z > 0.0),
            pos: surface.p,
            error: surface.error,
            n: stored_normal(tri),
            albedo,
            to_light: -(self.dir * (1.0 / len2.sqrt())),
            dist2: hit.t * hit.t * len2,
            cos_l: self.cos_l,
            pa: self.pa,
            power: self.le * (INV_PI / self.pa),
        }
    }
}

/// The first ray of the sampler's sample's light subpath (its uniforms keyed by `CONNECT_TAG`):
/// a point on a triangle light picked as next-event estimation picks it, a cosine-distributed
/// direction from it.
#[inline(always)]
pub fn light_ray(scene: &SceneView, v: Variant, rng: &Sampler) -> LightRay {
    let [ua, ub, uc, ud] = rng.independent_4d(CONNECT_TAG);
    let many = v.has(FEATURE_MANY_EMITTERS);
    let (index, u1) = pick_light(scene.lights, scene.light_count, many, ua);
    let light = scene.lights[index as usize];
    if light.triangle >= LIGHT_NOT_TRIANGLE {
        return LightRay::NONE;
    }
    let lmat = &scene.materials[scene.info[light.triangle as usize].material as usize];
    let le = Vec3::new(lmat.emission.x, lmat.emission.y, lmat.emission.z);
    let lp = light_point(&scene.triangles[light.triangle as usize], u1, ub);
    let (on_light, nl) = (lp.at, lp.n);
    let local = cosine_hemisphere(uc, ud);
    let (tb, bb) = orthonormal_basis(nl);
    let dir = tb * local.x + bb * local.y + nl * local.z;
    LightRay {
        ok: (local.z > 0.0) & ((le.x > 0.0) | (le.y > 0.0) | (le.z > 0.0)),
        origin: offset_ray_origin(on_light.p, on_light.error, nl),
        dir,
        cos_l: local.z,
        pa: light.pmf / light.area,
        le,
    }
}

/// The segment joining an eye vertex to a light vertex, and the cosines the weights need.
#[derive(Clone, Copy)]
pub(crate) struct Link {
    /// Both ends face each other and the light vertex faces its light point.
    pub(crate) ok: bool,
    /// The segment's geometry term, |cos| at both ends over the squared distance.
    pub(crate) geo: f32,
    /// The cosine at the light vertex toward its light point, on the eye vertex's side.
    pub(crate) cos_yl: f32,
    /// The eye vertex lies on the side the light vertex's stored normal points away from.
    pub(crate) behind: bool,
}

impl Link {
    /// The link from an eye vertex at `pos` (flat normal `nf` toward the ray's origin) to a
    /// light vertex at `y`, stored normal `ny`, `ny_to_light` the cosine of `ny` to its light
    /// point. Taken on the eye's side the cosine changes sign exactly, so a pooled record
    /// keeps one cosine for both sides.
    #[inline(always)]
    pub fn new(pos: Vec3, nf: Vec3, y: Vec3, ny: Vec3, ny_to_light: f32) -> Link {
        let d = y - pos;
        let dist2 = dot(d, d);
        let w = d * (1.0 / dist2.sqrt());
        let cos_e = dot(nf, w);
        let cos_ye = dot(ny, w);
        let behind = cos_ye < 0.0;
        let cos_yl = if behind { ny_to_light } else { -ny_to_light };
        Link { ok: (cos_e > 0.0) & (cos_yl > 0.0) & (dist2 > 0.0), geo: cos_e * cos_ye.abs() / dist2, cos_yl, behind }
    }

    /// The light vertex's normal on the eye vertex's side.
    #[inline(always)]
    pub fn toward_eye(&self, ny: Vec3) -> Vec3 {
        if self.behind {
            ny
        } else {
            -ny
        }
    }

    /// The power-heuristic weight of the connection among the three strategies that make its
    /// path, over the path's last two segments: the light vertex's BSDF sample toward the eye
    /// vertex with the light sample there (q0); the light subpath (`q1`); the connection (q2:
    /// `pa`, the light point's area density, times cos_yl / pi over the eye vertex's area
    /// density from the light vertex, geo / pi), counted `kappa` times (`connection_weight`).
    #[inline(always)]
    pub fn weight(&self, pa: f32, q1: f32, kappa: f32) -> f32 {
        let q0 = self.cos_yl * INV_PI;
        let q2 = pa * self.cos_yl / self.geo * kappa;
        power_heuristic3(q2, q0, q1)
    }
}

/// A pooled candidate's segment (`Link` for a record) and its weight, in two divisions and no
/// square root: with κ `POOL_WEIGHT`, P = κ pa cos_yl and q2 = P / geo, the power heuristic
/// q2² / (q2² + q0² + q1²) is 1 / (1 + (q0² + q1²) (geo / P)²), and the record holds 1 / P
/// (`inv_p`) and q0² + q1² (`q01`); cos_yl enters only as |`ny_to_light`| where the link is
/// open. The products stay within the squared distance's range at any scale.
#[derive(Clone, Copy)]
pub(crate) struct PooledLink {
    pub(crate) ok: bool,
    /// The geometry term times the MIS weight.
    pub(crate) term: f32,
    pub(crate) behind: bool,
}

impl PooledLink {
    #[inline(always)]
    pub fn new(pos: Vec3, nf: Vec3, y: Vec3, ny: Vec3, ny_to_light: f32, inv_p: f32, q01: f32) -> PooledLink {
        let d = y - pos;
        let dist2 = dot(d, d);
        // Both cosines times the distance.
        let (cos_e, cos_ye) = (dot(nf, d), dot(ny, d));
        let behind = cos_ye < 0.0;
        let cos_yl = if behind { ny_to_light } else { -ny_to_light };
        let inv = 1.0 / dist2;
        let geo = cos_e * inv * (cos_ye.abs() * inv);
        let r = geo * inv_p;
        let term = geo / (1.0 + q01 * (r * r));
        PooledLink { ok: (cos_e > 0.0) & (cos_yl > 0.0) & (dist2 > 0.0), term, behind }
    }
}

/// The connection strategy at an eye vertex (Lambertian, flat normal `nf` toward the ray's
/// origin): its path through the light subpath's vertex, MIS-weighted against the path
/// tracer's two ways of making the same path. Returns the shadow ray (none where the two do
/// not face each other) and the radiance it adds if it gets through (`shadow`).
#[inline(always)]
pub fn connect(lv: &LightVertex, pos: Vec3, spawn: Vec3, nf: Vec3, albedo: Vec3, beta: Vec3) -> (ShadowRay, Vec3) {
    let link = Link::new(pos, nf, lv.pos, lv.n, dot(lv.n, lv.to_light));
    let mut out = (ShadowRay::NONE, Vec3::ZERO);
    if lv.valid & link.ok {
        let w2 = link.weight(lv.pa, lv.q1(), 1.0);
        let target = offset_ray_origin(lv.pos, lv.error, link.toward_eye(lv.n));
        out = (ShadowRay::toward(spawn, target), beta * albedo * lv.albedo * lv.power * (link.geo * w2));
    }
    out
}

/// The pooled connection at an eye vertex (Lambertian, flat normal `nf` toward the ray's
/// origin) at bounce `bounce` of `rng`'s sample: weighs the `pool_candidates(bounce)` records of the
/// sample's block that it takes from its group's window (`pool_window`, `pool_slot`) by their
/// unshadowed contributions (MIS-weighted as `connect`'s), picks one in proportion and adds its
/// contribution times the mean weight over the picked one's, if a shadow ray reaches it: returns
/// that ray (none where no candidate weighs anything) and that contribution (`shadow`).
#[inline(always)]
// Index loops over the weights: the kernel's code keeps to them rather than slice iterators.
#[allow(clippy::too_many_arguments, clippy::needless_range_loop)]
pub fn connect_pooled(
    scene: &SceneView,
    rng: &Sampler,
    bounce: u32,
    pos: Vec3,
    spawn: Vec3,
    nf: Vec3,
    albedo: Vec3,
    beta: Vec3,
) -> (ShadowRay, Vec3) {
    let window = pool_window(rng.group_bits(POOL_WINDOW_TAG + bounce, POOL_STRIDE));
    let (lane, u) = (rng.sample() % POOL_STRIDE, rng.independent_4d(POOL_PICK_TAG + bounce)[0]);
    let (records, at) = (scene.light_pool.records, scene.light_pool.offset(rng.sample()));
    let beta_albedo = beta * albedo;
    let candidates = pool_candidates(bounce);
    let mut w = [0.0f32; POOL_CANDIDATES];
    let mut sum = 0.0f32;
    for j in 0..candidates {
        let (link, bw, _) = pooled_candidate(records, at + pool_slot(window, lane, j), pos, nf, beta_albedo);
        if link.ok {
            // The sum of the contribution's channels written with its common factor taken out,
            // as Mesa's optimiser (lavapipe) rewrites `a·b + a·c` anyway.
            let wj = (bw.x + bw.y + bw.z) * link.term;
            if (wj > 0.0) & (wj <= f32::MAX) {
                w[j] = wj;
                sum += wj;
            }
        }
    }
    if !((sum > 0.0) & (sum <= f32::MAX)) {
        return (ShadowRay::NONE, Vec3::ZERO);
    }
    let mut pick = u * sum;
    let mut y = 0;
    for j in 0..candidates {
        let wj = w[j];
        if wj > 0.0 {
            y = j;
            if pick < wj {
                break;
            }
            pick -= wj;
        }
    }
    // The picked candidate's link and contribution found again, rather than kept for each.
    let slot = at + pool_slot(window, lane, y);
    let (link, bw, (point, ny)) = pooled_candidate(records, slot, pos, nf, beta_albedo);
    let error = Vec3::splat(pool_field(records, slot, 12));
    let target = offset_ray_origin(point, error, if link.behind { ny } else { -ny });
    (ShadowRay::toward(spawn, target), bw * link.term * (sum / (candidates as f32 * w[y])))
}

/// The pool record at `records[slot]` (its first field; `pool_index`) as a candidate for the
/// eye vertex at `pos`: its link, its unshadowed contribution before the link's term (β times
/// the albedos and the subpath's power) and its point and normal.
/// Functions of the slice rather than closures over it: rust-gpu keeps a closure's captured
/// slice as a struct holding a pointer, which naga rejects.
#[inline(always)]
fn pooled_candidate(
    records: &[f32],
    slot: usize,
    pos: Vec3,
    nf: Vec3,
    beta_albedo: Vec3,
) -> (PooledLink, Vec3, (Vec3, Vec3)) {
    let (y, ny) = (pool_field3(records, slot, 0), pool_field3(records, slot, 3));
    let (cos, inv_p, q01) = (pool_field(records, slot, 6), pool_field(records, slot, 7), pool_field(records, slot, 8));
    let link = PooledLink::new(pos, nf, y, ny, cos, inv_p, q01);
    (link, beta_albedo * pool_field3(records, slot, 9), (y, ny))
}

/// Field `f` of the pool record at `records[slot]`.
#[inline(always)]
fn pool_field(records: &[f32], slot: usize, f: usize) -> f32 {
    records[slot + pool_index(0, f, 0)]
}

/// Fields `f` to `f + 2` of the pool record at `records[slot]`.
#[inline(always)]
fn pool_field3(records: &[f32], slot: usize, f: usize) -> Vec3 {
    Vec3::new(pool_field(records, slot, f), pool_field(records, slot, f + 1), pool_field(records, slot, f + 2))
}

/// Light vertices the eye vertex at bounce `bounce` weighs: `POOL_CANDIDATES` at the camera
/// ray's hit, then 24, 16 and 8 from the fourth vertex on (the first rows of its window). A
/// deeper vertex's connection carries less of the pixel's light (its throughput has fallen by
/// the albedos on the way), so a better pick there buys less than the candidates cost; the
/// estimate is unbiased for any count, and the strategy's weight (`POOL_WEIGHT`) stays.
#[inline(always)]
pub fn pool_candidates(bounce: u32) -> usize {
    match bounce {
        0 => POOL_CANDIDATES,
        1 => 24,
        2 => 16,
        _ => 8,
    }
}

/// The first slot of a window of candidates from 32 hashed bits: a multiple of `POOL_STRIDE`.
#[inline(always)]
pub fn pool_window(bits: u32) -> u32 {
    (bits >> (32 - POOL_WINDOW_BITS)) * POOL_STRIDE
}

/// Candidate `j`'s slot for the sample at `lane` of its group (`sample % POOL_STRIDE`), in the
/// window from `window`, wrapping in the block.
#[inline(always)]
pub fn pool_slot(window: u32, lane: u32, j: usize) -> usize {
    (((window + POOL_STRIDE * j as u32) & (POOL_SLOTS - 1)) + lane) as usize
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{pcg4d, u32_to_unit_f32};

    /// Every eye vertex weighs at least one candidate, or its connection strategy, which the
    /// other strategies' weights count on, would be missing; and no more than a window's rows.
    #[test]
    fn every_bounce_weighs_some_candidates_of_its_window() {
        let mut last = POOL_CANDIDATES;
        for bounce in [0, 1, 2, 3, 4, 5, 6, 100, u32::MAX] {
            let n = pool_candidates(bounce);
            assert!((1..=last).contains(&n), "bounce {bounce}: {n} candidates after {last}");
            last = n;
        }
        assert_eq!(pool_candidates(0), POOL_CANDIDATES, "the first hit weighs the whole window");
    }

    /// `PooledLink` is `Link` with its weight at κ = `POOL_WEIGHT` from a record's terms, and
    /// stays so from the smallest scene scale to the largest (positions times `scale`, the light
    /// point's area density over its square; the term is then over `scale²`).
    #[test]
    fn pooled_link_is_link_and_its_weight_at_every_scale() {
        let mut k = 0u32;
        let mut next = || {
            k += 1;
            pcg4d(k, 7, 11, 13).map(|h| u32_to_unit_f32(h) * 2.0 - 1.0)
        };
        let (mut open, mut compared) = (0, 0);
        for _ in 0..4000 {
            let [a, b, c, d] = next();
            let [e, f, g, h] = next();
            let [i, j, l, m] = next();
            let (pos, y) = (Vec3::new(a, b, c), Vec3::new(d, e, f) * 3.0);
            let (nf, ny) = (Vec3::new(g, h, i).normalize(), Vec3::new(j, l, m).normalize());
            let [cos, pa, q1, _] = next();
            let (pa, q1) = (pa.abs() * 4.0 + 0.01, q1.abs() * 3.0 + 0.001);
            let link = Link::new(pos, nf, y, ny, cos);
            let want = link.geo * link.weight(pa, q1, POOL_WEIGHT);
            for scale in [1e-10f32, 1.0, 1e12] {
                let pa = pa / (scale * scale);
                let q0 = cos * INV_PI;
                let (inv_p, q01) = (1.0 / (POOL_WEIGHT * pa * cos.abs()), q0 * q0 + q1 * q1);
                let pooled = PooledLink::new(pos * scale, nf, y * scale, ny, cos, inv_p, q01);
                assert_eq!((pooled.ok, pooled.behind), (link.ok, link.behind), "scale {scale}");
                if link.ok {
                    let got = pooled.term * scale * scale;
                    assert!((got - want).abs() <= 1e-4 * want, "scale {scale}: {got} against {want}");
                    compared += 1;
                }
            }
            open += usize::from(link.ok);
        }
        assert!(open > 400 && compared == 3 * open, "{open} open links, {compared} compared");
    }
}
