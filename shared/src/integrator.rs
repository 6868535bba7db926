//! Unidirectional path tracing with next-event estimation to emissive triangles, combined with
//! BSDF sampling by multiple importance sampling (Veach & Guibas 1995, power heuristic),
//! Russian roulette and a bounce limit (pbrt-v4 §13.4 `PathIntegrator`).
//!
//! Bounce counting: `max_bounces` counts indirect bounces, so 0 renders direct light only (a path
//! of at most two segments after the camera: Mitsuba's `max_depth = max_bounces + 2`).
//!
//! Every function takes the `Variant` it runs as: what the scene's feature set leaves out is not
//! done, and in a specialised build (a CPU monomorph, a GPU pipeline with specialisation
//! constants) not compiled either.
//!
//! A vertex's shadow rays, next-event estimation's and the connection's, are prepared first
//! (`shadow`) and traced by the path loop's one query, the one that finds the path's vertices, so
//! that a shader holds one copy of the traversal.
//!
//! `trace_sample_recorded` runs a sample with a `record::Recorder` that hears of each event (rays,
//! hits, emission, light and BSDF samples, roulette); the renderers (`render_samples`) pass
//! `NoRecord`, whose hooks compile to nothing.
use crate::camera::primary_direction;
use crate::connection::{
    connect, connect_pooled, connection_weight, connects, inv_pi_area, light_ray, LightRay, LightVertex,
};
use crate::environment;
use crate::exp::exp_neg;
use crate::features::{
    Variant, FEATURE_EMITTERS, FEATURE_ENVIRONMENT, FEATURE_ENVIRONMENT_MAP, FEATURE_INDIRECT, FEATURE_MANY_EMITTERS,
    FEATURE_PUNCTUAL,
};
use crate::glam::{Vec3, Vec4};
use crate::kdtree::Hit;
use crate::layout::{
    Material, RenderParams, AOV_ALBEDO, AOV_COST, AOV_NORMAL, LIGHT_NOT_TRIANGLE, NO_ENVIRONMENT_MAP, NO_HIT, NO_LIGHT,
};
use crate::light_sample::{light_sample_toward, other_light_direction, triangle_light_direction, Shading};
use crate::material::{absorption, albedo, emitted, is_delta, picks_lobe, sample as sample_bsdf, transmits};
use crate::numerics::{offset_ray_origin, sanitize};
use crate::raycast::{query_recorded, Traced};
use crate::record::{
    BsdfEvent, Gated, LightEvent, NoRecord, Recorder, SurfaceEvent, END_ABSORBED, END_AOV, END_BOUNCE_LIMIT,
    END_ESCAPED, END_ROULETTE, LIGHT_DELTA, RAY_BOUNCE, RAY_CAMERA, RAY_SHADOW,
};
use crate::rng::Sampler;
use crate::sampling::{pick_light, power_heuristic, power_heuristic3};
use crate::scene::SceneView;
use crate::shadow::{LightSample, ShadowRay};
#[cfg(target_arch = "spirv")]
use crate::surface::material_at;
use crate::surface::{consistent, hit_weights, shading_normal};
#[cfg(not(target_arch = "spirv"))]
use crate::surface::{looks_up_textures, resolve};
use crate::triangle::{geometric_normal, hit_point, stored_normal, TriangleHit};
use crate::vecmath::{dot, length, length_squared, max_component, normalize, xyz};
#[allow(unused_imports)]
use spirv_std::num_traits::Float;

/// Shadow rays stop this fraction short of the light (pbrt's `ShadowEpsilon`).
pub const SHADOW_EPSILON: f32 = 1e-4;
/// Russian roulette never keeps a path with probability above this.
pub(crate) const RR_MAX_SURVIVAL: f32 = 0.95;

/// One camera sample's radiance and the triangle its camera ray hit first.
#[derive(Clone, Copy)]
pub struct PathSample {
    pub radiance: Vec3,
    pub primary: u32,
}

/// The state a path carries from vertex to vertex.
struct Path {
    origin: Vec3,
    dir: Vec3,
    /// Throughput: the product of BSDF weights so far.
    beta: Vec3,
    radiance: Vec3,
    /// Solid-angle pdf of the BSDF sample that produced `dir`; unused for camera rays.
    bsdf_pdf: f32,
    /// Indirect bounces taken: 0 while the camera ray is traced.
    bounce: u32,
    /// The previous vertex's 1 / (pi * its area density from the vertex before), 0 where the
    /// connection cannot make the path; and |nf . wi| there.
    prev_inv_pi_a: f32,
    prev_cos: f32,
    /// Whether the light subpath connects to the eye vertices (`connects`).
    bidir: bool,
}

/// Traces sample `sample` of pixel (px, py), telling `rec` of every event on the path
/// (`record::Recorder`): the same code, so the same values, whatever the recorder.
#[inline(always)]
pub fn trace_sample_recorded<R: Recorder>(
    scene: &SceneView,
    p: &RenderParams,
    v: Variant,
    px: u32,
    py: u32,
    sample: u32,
    rec: &mut R,
) -> PathSample {
    trace_path(scene, p, v, px, py, Sampler::new(p.sampler, py * p.width + px, sample, p.seed), rec)
}

/// `trace_sample_recorded` with the sample's sampler made by the caller (`render_samples` makes
/// it from the pixel's seeds, computed once).
///
/// Every ray of the path goes through the loop's one query, one ray an iteration (`STAGE_*`):
/// the light subpath's first ray, where there is one, then per vertex the ray that finds it,
/// next-event estimation's shadow ray and the connection's. A shader inlines the traversal once
/// per query, so the kernel holds one copy of it; on a GPU the lanes of a subgroup then
/// traverse together whatever ray each has, as in a persistent-thread traversal (Aila & Laine,
/// "Understanding the Efficiency of Ray Traversal on GPUs", HPG 2009).
///
/// The loop has a single exit (`alive`) and the vertex work lives in `shade_vertex`,
/// `connect_vertex` and `leave_vertex`, which return early but contain no loop: a `break` out
/// of this loop from inside inlined traversal code was miscompiled for whole subgroups on
/// lavapipe (Mesa 22.3, LLVM 15), which lost every lane's sample when one lane left the loop
/// that way.
#[inline(always)]
fn trace_path<R: Recorder>(
    scene: &SceneView,
    p: &RenderParams,
    v: Variant,
    px: u32,
    py: u32,
    mut rng: Sampler,
    rec: &mut R,
) -> PathSample {
    let (jx, jy) = rng.next_2d();
    let mut path = Path {
        origin: xyz(p.eye),
        dir: primary_direction(p, px as f32 + jx, py as f32 + jy),
        beta: Vec3::ONE,
        radiance: Vec3::ZERO,
        bsdf_pdf: 0.0,
        bounce: 0,
        bidir: false,
        prev_inv_pi_a: 0.0,
        prev_cos: 0.0,
    };
    path.bidir = connects(scene, p, v);
    // Not a field of `Path`: naga sizes a struct holding `Vec3`s to a multiple of 16 bytes, so
    // nested in another one its end would overlap the next member.
    let light = if path.bidir & (p.light_pool == 0) { light_ray(scene, v, &rng) } else { LightRay::NONE };
    let mut lv = LightVertex::NONE;
    // The vertex being shaded between its rays: its shading point, its material (`store`, see
    // `vertex_material`), its light sample, and the shadow ray of a shadow stage with what the
    // connection adds if that ray gets through.
    let mut vx = Vertex::NONE;
    let mut store = Material::default();
    let mut nee = NO_LIGHT_SAMPLE;
    let mut shadow = ShadowRay::NONE;
    let mut linked = Vec3::ZERO;
    let mut stage = if light.ok { STAGE_LIGHT } else { STAGE_PATH };
    let mut primary = NO_HIT;
    let mut alive = true;
    while alive {
        let path_ray = stage == STAGE_PATH;
        let (origin, dir, t_max, cast) = if stage == STAGE_LIGHT {
            (light.origin, light.dir, f32::MAX, true)
        } else if path_ray {
            (path.origin, path.dir, f32::MAX, true)
        } else {
            (shadow.from, shadow.dir, shadow.t_max, shadow.active)
        };
        // The recorder hears of every ray but the light subpath's.
        let heard = cast & (stage != STAGE_LIGHT);
        if heard {
            let kind = if !path_ray {
                RAY_SHADOW
            } else if path.bounce == 0 {
                RAY_CAMERA
            } else {
                RAY_BOUNCE
            };
            rec.ray(kind, origin, dir, t_max);
        }
        let mut traced = Traced { hit: Hit::miss(t_max), restarts: 0 };
        if cast {
            let gated = &mut Gated { rec: &mut *rec, on: heard };
            traced = query_recorded(scene, p.traversal, origin, dir, t_max, !path_ray & (stage != STAGE_LIGHT), gated);
        }
        let hit = traced.hit;
        if heard {
            rec.traced(hit.triangle, hit.t, hit.nodes, hit.tests, traced.restarts);
        }
        let open = cast & !hit.is_hit();
        if stage == STAGE_LIGHT {
            lv = light.vertex(scene, &hit);
            stage = STAGE_PATH;
        } else if path_ray {
            if path.bounce == 0 {
                primary = hit.triangle;
            }
            if (path.bounce == 0) & (p.aov == AOV_COST) {
                // The cost image: the camera ray's traversal work instead of radiance.
                path.radiance = Vec3::new(hit.nodes as f32, hit.tests as f32, traced.restarts as f32);
                rec.end(END_AOV, path.radiance);
                alive = false;
            } else if hit.is_hit() {
                vx.copied = load_material(scene, v, &hit, &mut store);
                vx.material = scene.info[hit.triangle as usize].material;
                let mat = vertex_material(scene, &store, &vx);
                // The first hit's albedo or shading normal too (`shade_vertex`).
                alive = shade_vertex(scene, p, v, &mut path, &mut rng, &hit, mat, &mut vx, &mut nee, rec);
                shadow = nee.ray;
                stage = STAGE_LIGHT_SAMPLE;
            } else if (path.bounce == 0) & first_hit_aov(p) {
                // No first hit: the albedo or normal image is black there.
                rec.end(END_AOV, path.radiance);
                alive = false;
            } else {
                if v.has(FEATURE_ENVIRONMENT_MAP) & (p.environment_map != NO_ENVIRONMENT_MAP) {
                    // The map, MIS-weighted against its sampling by next-event estimation (the
                    // camera ray and a delta BSDF's ray take it whole).
                    let (le, weight) = map_seen(scene, p.environment_map - 1, path.dir, path.bounce, path.bsdf_pdf);
                    let added = path.beta * le * weight;
                    path.radiance += added;
                    rec.escaped(added);
                } else if v.has(FEATURE_ENVIRONMENT) {
                    let added = path.beta * xyz(p.environment);
                    path.radiance += added;
                    rec.escaped(added);
                } else {
                    rec.escaped(Vec3::ZERO);
                }
                rec.end(END_ESCAPED, path.radiance);
                alive = false;
            }
        } else if stage == STAGE_LIGHT_SAMPLE {
            if has_lights(scene, v) {
                nee.finish(open, &mut path.radiance, rec);
            }
            let mat = vertex_material(scene, &store, &vx);
            (shadow, linked) = connect_vertex(scene, p, v, &path, &mut rng, &lv, mat, &vx);
            stage = STAGE_CONNECTION;
        } else {
            if open {
                path.radiance += linked;
            }
            if path.bidir & (path.bounce < v.max_bounces) {
                rec.connection(shadow.active, if open { linked } else { Vec3::ZERO });
            }
            let mat = vertex_material(scene, &store, &vx);
            alive = leave_vertex(v, &mut path, &mut rng, mat, &vx, scene, rec);
            stage = STAGE_PATH;
        }
    }
    PathSample { radiance: path.radiance, primary }
}

/// What the path loop's iteration traces (`trace_path`): the light subpath's first ray, the ray
/// that finds the path's next vertex, next-event estimation's shadow ray, the connection's.
const STAGE_LIGHT: u32 = 0;
const STAGE_PATH: u32 = 1;
const STAGE_LIGHT_SAMPLE: u32 = 2;
const STAGE_CONNECTION: u32 = 3;

/// What a vertex keeps between its rays (`trace_path`): the shading point (see `Shading`), the
/// area density the connection's weight needs, the BSDF set's uniforms, and where its material
/// is (`vertex_material`).
#[derive(Clone, Copy)]
struct Vertex {
    pos: Vec3,
    spawn: Vec3,
    error: Vec3,
    nf: Vec3,
    ns: Vec3,
    wo: Vec3,
    front: bool,
    inv_pi_a: f32,
    ub1: f32,
    ub2: f32,
    u_roulette: f32,
    /// The material's index, and whether the vertex reads a copy of it instead (`store`).
    material: u32,
    copied: bool,
}

impl Vertex {
    const NONE: Vertex = Vertex {
        pos: Vec3::ZERO,
        spawn: Vec3::ZERO,
        error: Vec3::ZERO,
        nf: Vec3::Z,
        ns: Vec3::Z,
        wo: Vec3::Z,
        front: true,
        inv_pi_a: 0.0,
        ub1: 0.0,
        ub2: 0.0,
        u_roulette: 0.0,
        material: 0,
        copied: false,
    };
}

/// Puts the material at `hit` into `store` where the vertex needs a copy: with its textures
/// looked up at the hit (`surface::resolve`), and on a GPU always. Returns whether it did.
#[inline(always)]
fn load_material(scene: &SceneView, v: Variant, hit: &Hit, store: &mut Material) -> bool {
    #[cfg(target_arch = "spirv")]
    {
        *store = material_at(scene, v, hit);
        true
    }
    #[cfg(not(target_arch = "spirv"))]
    {
        let base = &scene.materials[scene.info[hit.triangle as usize].material as usize];
        let copied = looks_up_textures(scene, v, base);
        if copied {
            *store = resolve(scene, v, base, hit.triangle, hit_weights(hit));
        }
        copied
    }
}

/// The material vertex `vx` shades with: on the CPU the scene's own entry where no texture is
/// looked up (a copy of its 144 bytes at every vertex cost measurable time on diffuse scenes),
/// else the copy in `store` (`load_material`). A shader always reads its copy: it cannot choose
/// between a pointer into a storage buffer and one to a local variable.
#[inline(always)]
fn vertex_material<'a>(scene: &SceneView<'a>, store: &'a Material, vx: &Vertex) -> &'a Material {
    #[cfg(target_arch = "spirv")]
    {
        let _ = (scene, vx);
        store
    }
    #[cfg(not(target_arch = "spirv"))]
    if vx.copied {
        store
    } else {
        &scene.materials[vx.material as usize]
    }
}

/// Whether next-event estimation has lights to sample. Also the lane integrator's.
#[inline(always)]
pub(crate) fn has_lights(scene: &SceneView, v: Variant) -> bool {
    (v.has(FEATURE_EMITTERS) | v.has(FEATURE_ENVIRONMENT_MAP) | v.has(FEATURE_PUNCTUAL)) & (scene.light_count > 0)
}

/// Whether the render is the image of the first hits' albedo or shading normal (for denoisers
/// and debugging).
#[inline(always)]
fn first_hit_aov(p: &RenderParams) -> bool {
    (p.aov == AOV_ALBEDO) | (p.aov == AOV_NORMAL)
}

/// The environment map (at `o` in the texture words) seen by a ray leaving the scene along
/// `dir`: its radiance and the MIS weight against its sampling by next-event estimation (one
/// for the camera ray, `bounce` 0, and for a delta BSDF's ray, whose `bsdf_pdf` takes it whole).
/// Also the lane integrator's, lane by lane.
#[inline(always)]
pub(crate) fn map_seen(scene: &SceneView, o: u32, dir: Vec3, bounce: u32, bsdf_pdf: f32) -> (Vec3, f32) {
    let at = environment::locate(scene.textures, o, dir);
    let le = environment::radiance(scene.textures, o, &at);
    let mut weight = 1.0;
    if bounce > 0 {
        let light_pdf = environment::selection_pmf(scene.textures, o) * environment::density(scene.textures, o, &at);
        weight = power_heuristic(bsdf_pdf, light_pdf);
    }
    (le, weight)
}

/// What a ray that reached a surface of material `mat` from behind (geometric normal `ng`,
/// direction `dir`, distance `t` in units of `dir`) keeps of its throughput after crossing the
/// medium inside: e^(−σ·distance) per channel for an absorbing medium (KHR_materials_volume),
/// one otherwise (an exact factor). Also the lane integrator's, lane by lane.
#[inline(always)]
pub(crate) fn medium_transmittance(v: Variant, mat: &crate::layout::Material, ng: Vec3, dir: Vec3, t: f32) -> Vec3 {
    let sigma = absorption(v, mat);
    if ((sigma.x > 0.0) | (sigma.y > 0.0) | (sigma.z > 0.0)) && dot(ng, dir) > 0.0 {
        let d = t * length(dir);
        return Vec3::new(exp_neg(-sigma.x * d), exp_neg(-sigma.y * d), exp_neg(-sigma.z * d));
    }
    Vec3::ONE
}

/// The shading normal `n` turned toward the side the ray (direction `dir`) arrived from, and
/// whether that is the front (counter-clockwise) side, judged by the geometric normal `ng`.
#[inline(always)]
fn facing(ng: Vec3, n: Vec3, dir: Vec3) -> (Vec3, bool) {
    let front = dot(ng, dir) < 0.0;
    (if front { n } else { -n }, front)
}

/// The light event of a vertex whose material is a delta, which takes no light sample.
const DELTA_LIGHT_EVENT: LightEvent = LightEvent {
    status: LIGHT_DELTA,
    light: 0,
    triangle: 0,
    point: Vec3::ZERO,
    light_pdf: 0.0,
    bsdf_pdf: 0.0,
    mis_weight: 0.0,
    contribution: Vec3::ZERO,
};

/// The light sample of a vertex that takes none (a delta material, a scene without lights).
const NO_LIGHT_SAMPLE: LightSample = LightSample { event: DELTA_LIGHT_EVENT, ray: ShadowRay::NONE, added: Vec3::ZERO };

/// A path vertex up to its shadow rays: emission (MIS-weighted against light sampling) and
/// next-event estimation's light sample (`nee`, its shadow ray not yet traced); the shading
/// point goes to `vx`. Returns whether the vertex goes on to its shadow rays
/// (`connect_vertex`) and its BSDF sample (`leave_vertex`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn shade_vertex<R: Recorder>(
    scene: &SceneView,
    p: &RenderParams,
    v: Variant,
    path: &mut Path,
    rng: &mut Sampler,
    hit: &Hit,
    mat: &Material,
    vx: &mut Vertex,
    nee: &mut LightSample,
    rec: &mut R,
) -> bool {
    let dir = path.dir;
    // Without indirect light every vertex after the first adds exactly zero (nothing reflects,
    // or nothing emits): the path ends at its first hit, after that hit's emission.
    let last = !v.has(FEATURE_INDIRECT) | (path.bounce == v.max_bounces + 1);
    let lights = has_lights(scene, v);
    // This vertex's sample sets, drawn first: each is a chain of dependent hashes and
    // multiplications (`sobol`), which a CPU overlaps with the shading below when they start
    // here, not where their values are needed. The order of the sets is unchanged: the light
    // set (when there are lights), then the BSDF set; the last vertex draws none.
    let (u_select, u_light) = if lights & !last { rng.next_2d() } else { (0.0, 0.0) };
    [vx.ub1, vx.ub2, vx.u_roulette] = if last { [0.0; 3] } else { rng.next_3d() };
    let tri = &scene.triangles[hit.triangle as usize];
    let info = scene.info[hit.triangle as usize];
    let ng = geometric_normal(tri);
    let n = stored_normal(tri);
    let surface = hit_point(tri, &TriangleHit { t: hit.t, u: hit.u, v: hit.v, w: hit.w });
    let pos = surface.p;
    if R::ACTIVE {
        // The shading normal as the BSDFs below see it, also at a last vertex, which shades
        // nothing; computed again there, only for a recorder.
        let (nf, front) = facing(ng, n, dir);
        let ns = shading_normal(scene, v, hit.triangle, hit_weights(hit), nf, -normalize(dir));
        rec.surface(SurfaceEvent {
            bounce: path.bounce,
            position: pos,
            triangle: hit.triangle,
            material: info.material,
            material_kind: mat.kind,
            geometric_normal: n,
            shading_normal: ns,
            front,
        });
    }

    path.beta *= medium_transmittance(v, mat, ng, dir, hit.t);

    // The albedo or shading normal image ends the path at its first hit, once the shading
    // normal is known, through the same code as the radiance (a shader holds one copy of the
    // material's and the normal's lookups); nothing is added to it before.
    let aov = (path.bounce == 0) & first_hit_aov(p);
    // Only emitters emit, and every emitter is in the light table.
    let le = if v.has(FEATURE_EMITTERS) & !aov { emitted(mat, ng, dir) } else { Vec3::ZERO };
    if (le.x > 0.0) | (le.y > 0.0) | (le.z > 0.0) {
        let mut weight = 1.0;
        if (path.bounce > 0) & (info.light != NO_LIGHT) {
            let light = scene.lights[info.light as usize];
            let dist2 = hit.t * hit.t * length_squared(dir);
            let cos_l = dot(n, normalize(dir)).abs();
            let light_pdf = light.pmf * dist2 / (cos_l * light.area);
            weight = if path.bidir {
                let q2 = light.pmf / light.area * path.prev_cos * path.prev_inv_pi_a * connection_weight(p);
                power_heuristic3(path.bsdf_pdf, light_pdf, q2)
            } else {
                power_heuristic(path.bsdf_pdf, light_pdf)
            };
        }
        let added = path.beta * le * weight;
        path.radiance += added;
        rec.emission(le, weight, added);
    }
    if last & !aov {
        rec.end(END_BOUNCE_LIMIT, path.radiance);
        return false;
    }

    // Shade on the side the ray arrived from: the materials are two-sided.
    // Rays leave along the flat normal `nf`; the BSDFs see the shading normal `ns`, which is
    // `nf` without vertex normals (`surface::shading_normal`).
    let (nf, front) = facing(ng, n, dir);
    let spawn = offset_ray_origin(pos, surface.error, nf);
    let wo = -normalize(dir);
    let ns = shading_normal(scene, v, hit.triangle, hit_weights(hit), nf, wo);
    if aov {
        path.radiance = if p.aov == AOV_NORMAL { ns } else { albedo(v, mat) };
        rec.end(END_AOV, path.radiance);
        return false;
    }
    // This vertex's area density from the vertex before (BSDF-sampled there), for the
    // connection strategy's MIS weight.
    let inv_pi_a = if path.bidir & (path.bounce > 0) { inv_pi_area(path.prev_cos, n, dir, hit.t) } else { 0.0 };

    *vx = Vertex { pos, spawn, error: surface.error, nf, ns, wo, front, inv_pi_a, ..*vx };
    // Next-event estimation's light sample and the connection each cast a shadow ray: both are
    // prepared and traced by the path loop's query (`shadow`), light sample first.
    *nee = NO_LIGHT_SAMPLE;
    // A smooth mirror reflects no sampled light: its reflection of an emitter counts in full
    // when the BSDF ray hits it (`DELTA_PDF` takes the whole MIS weight).
    if lights & !is_delta(v, mat) {
        // The set's best-spread pair picks the light and the point on it: the picking dimension,
        // rescaled within the picked light's interval, is the point's first coordinate, so the
        // points stay stratified over a light made of several triangles (a quad lamp). With one
        // light the pick is light 0 and the rescaling the identity (its interval is [0, 1]).
        let many = v.has(FEATURE_MANY_EMITTERS);
        let (index, u1) = pick_light(scene.lights, scene.light_count, many, u_select);
        let light = scene.lights[index as usize];
        let other = (v.has(FEATURE_ENVIRONMENT_MAP) | v.has(FEATURE_PUNCTUAL)) & (light.triangle >= LIGHT_NOT_TRIANGLE);
        // Where the sample lies and what arrives from there, by the light's kind; then one
        // evaluation of the BSDF toward it (`light_sample_toward`: a shader holds one copy).
        let d = if other {
            other_light_direction(scene, v, light.triangle, light.pmf, pos, u1, u_light)
        } else {
            triangle_light_direction(scene, v, &light, pos, u1, u_light)
        };
        // With connections a triangle's sample is one of three strategies (`connection`).
        let three = path.bidir & !other;
        let q2 = if three { d.pa * dot(nf, d.wi).abs() * inv_pi_a * connection_weight(p) } else { 0.0 };
        let at = Shading { pos, spawn, error: surface.error, nf, ns, wo, front };
        *nee = light_sample_toward(scene, v, path.beta, mat, &d, index, light.triangle, &at, three, q2);
    }
    true
}

/// The connection of vertex `vx` (of material `mat`) to a light subpath: its shadow ray, not yet
/// traced, and what it adds if the ray gets through; none past the bounce limit or without
/// connections.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn connect_vertex(
    scene: &SceneView,
    p: &RenderParams,
    v: Variant,
    path: &Path,
    rng: &mut Sampler,
    lv: &LightVertex,
    mat: &Material,
    vx: &Vertex,
) -> (ShadowRay, Vec3) {
    let mut link = (ShadowRay::NONE, Vec3::ZERO);
    if path.bidir & (path.bounce < v.max_bounces) {
        let albedo = Vec3::new(mat.albedo.x, mat.albedo.y, mat.albedo.z);
        link = if p.light_pool != 0 {
            connect_pooled(scene, rng, path.bounce, vx.pos, vx.spawn, vx.nf, albedo, path.beta)
        } else {
            connect(lv, vx.pos, vx.spawn, vx.nf, albedo, path.beta)
        };
    }
    link
}

/// The BSDF sample that continues the path from vertex `vx` (of material `mat`), and Russian
/// roulette. Returns whether the path goes on.
#[inline(always)]
fn leave_vertex<R: Recorder>(
    v: Variant,
    path: &mut Path,
    rng: &mut Sampler,
    mat: &Material,
    vx: &Vertex,
    scene: &SceneView,
    rec: &mut R,
) -> bool {
    let (ns, nf, wo, front) = (vx.ns, vx.nf, vx.wo, vx.front);
    // The lobe pick's uniform, drawn only for a material that has a choice.
    let picks = picks_lobe(v, mat);
    let u_pick = if picks { rng.independent_after() } else { 0.0 };
    let bs = sample_bsdf(v, mat, scene.textures, ns, wo, front, vx.ub1, vx.ub2, u_pick);
    let mut event = BsdfEvent {
        wi: bs.wi,
        pdf: bs.pdf,
        weight: bs.weight,
        picks_lobe: picks,
        u_pick,
        valid: false,
        throughput: path.beta,
    };
    if (bs.pdf <= 0.0) | !consistent(v, nf, ns, bs.wi) {
        rec.bsdf(event);
        rec.end(END_ABSORBED, path.radiance);
        return false;
    }
    path.beta *= bs.weight;
    if path.bidir {
        (path.prev_inv_pi_a, path.prev_cos) = (vx.inv_pi_a, dot(nf, bs.wi).abs());
    }
    event.valid = true;
    event.throughput = path.beta;
    rec.bsdf(event);
    path.bsdf_pdf = bs.pdf;
    path.bounce += 1;
    if path.bounce >= v.rr_start {
        let survive = max_component(path.beta).min(RR_MAX_SURVIVAL);
        if vx.u_roulette >= survive {
            rec.roulette(survive, vx.u_roulette, false, path.beta);
            rec.end(END_ROULETTE, path.radiance);
            return false;
        }
        path.beta /= survive;
        rec.roulette(survive, vx.u_roulette, true, path.beta);
    }
    // A refracted ray leaves from the far side of the surface.
    path.origin =
        if transmits(v, mat) & (dot(bs.wi, nf) < 0.0) { offset_ray_origin(vx.pos, vx.error, -nf) } else { vx.spawn };
    path.dir = bs.wi;
    true
}

/// Adds this pass's samples (`p.sample_start`, `p.sample_count`) of pixel (x, y) to its running
/// sums: what every renderer that gives all pixels the same samples (the CPU rows, both
/// full-frame GPU kernels) does per pixel and pass.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn render_pixel(
    scene: &SceneView,
    p: &RenderParams,
    v: Variant,
    x: u32,
    y: u32,
    sum: &mut Vec4,
    sum_sq: &mut Vec4,
    primary: &mut u32,
) {
    render_samples(scene, p, v, x, y, p.sample_start, p.sample_count, sum, sum_sq, primary);
}

/// Adds samples `[start, start + count)` of pixel (x, y) to its running sums, in sample order, so
/// every device sums the same numbers in the same order: `sum.xyz` radiance and `sum.w` the
/// number of samples that were non-finite or negative and were zeroed; `sum_sq.xyz` the squared
/// radiance, for the per-pixel variance (`sum_sq.w` unused). When the range holds sample 0,
/// `primary` gets the triangle its camera ray hit first.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn render_samples(
    scene: &SceneView,
    p: &RenderParams,
    v: Variant,
    x: u32,
    y: u32,
    start: u32,
    count: u32,
    sum: &mut Vec4,
    sum_sq: &mut Vec4,
    primary: &mut u32,
) {
    let mut acc = *sum;
    let mut acc_sq = *sum_sq;
    let mut s = start;
    let end = start + count;
    let pixel = y * p.width + x;
    #[cfg(not(target_arch = "spirv"))]
    let seeds = crate::rng::PixelSeeds::new(p.sampler, pixel, p.seed);
    while s < end {
        #[cfg(not(target_arch = "spirv"))]
        let rng = Sampler::with_seeds(p.sampler, pixel, s, p.seed, seeds);
        #[cfg(target_arch = "spirv")]
        let rng = Sampler::new(p.sampler, pixel, s, p.seed);
        let r = trace_path(scene, p, v, x, y, rng, &mut NoRecord);
        if s == 0 {
            *primary = r.primary;
        }
        let (l, bad) = sanitize(r.radiance, p.aov == AOV_NORMAL);
        acc += Vec4::new(l.x, l.y, l.z, if bad { 1.0 } else { 0.0 });
        acc_sq += Vec4::new(l.x * l.x, l.y * l.y, l.z * l.z, 0.0);
        s += 1;
    }
    *sum = acc;
    *sum_sq = acc_sq;
}

/// One pixel's share of a call for a row of pixels (`render_pixels_for`): its column and the
/// samples `[start, start + count)` it takes (none where `count` is 0).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelSpan {
    pub x: u32,
    pub start: u32,
    pub count: u32,
}

/// `render_samples` compiled for the feature set `F` (a CPU variant, monomorphised, so what `F`
/// leaves out is not in its code; `F = FEATURES_ALL` is the generic code) for each pixel of
/// `pixels`, all in row `y`, in turn, with each pixel's sums cut into runs of `per` samples:
/// sample `start + i` of pixel `k` is added to `sum[r * pixels.len() + k]` (and `sum_sq`),
/// `r = i / per`, each run in sample order, so each run's sums are the ones a call for that run
/// alone adds; pixel `k`'s primary hit goes to `primary[k]`. `runs` is the runs a pixel has at
/// most; `per` 0 counts as 1. The CPU renders two blocks of samples in one call this way and
/// keeps each block's sums apart, and takes a row at a time, so that the lane integrator
/// (`lanes::integrator::render_pixels_for`) fills its sixteen lanes from two blocks or from
/// several pixels. Inlined whole into its callers, so that a caller compiled for more
/// instructions (the CPU's AVX-512 copies) compiles all of it, traversal included, for them.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn render_pixels_for<const F: u32>(
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
    let n = pixels.len();
    let v = Variant::new(F, p);
    let per = per.max(1);
    for (k, px) in pixels.iter().enumerate() {
        let (end, mut s, mut run) = (px.start + px.count, px.start, 0);
        while s < end {
            let c = (end - s).min(per);
            let at = run * n + k;
            render_samples(scene, p, v, px.x, y, s, c, &mut sum[at], &mut sum_sq[at], &mut primary[k]);
            s += c;
            run += 1;
        }
        debug_assert!(run <= runs.max(1));
    }
}
