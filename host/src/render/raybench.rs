//! Ray-casting throughput for the three ray kinds of Aila & Laine, "Understanding the Efficiency
//! of Ray Traversal on GPUs" (HPG 2009): primary rays (coherent), ambient-occlusion rays (short,
//! any hit, from the primary hits) and diffuse-bounce rays (cosine-distributed, closest hit,
//! incoherent). No shading: only `shared::raycast::cast_ray`, on the CPU (rayon) or through the
//! ray-casting kernel.
//!
//! Alongside rays/s it reports the traversal's work per ray (nodes visited, triangles tested,
//! restarts) and an ideal rate (`ideal_mrays_per_s`), our stand-in for Aila & Laine's simulated
//! upper bound: measured/ideal shows what incoherence (divergence, cache misses) costs each kind.
use crate::render::gpu::Gpu;
use crate::render::Compiled;
use crate::settings::{RenderSettings, Traversal};
use anyhow::{bail, Result};
use rayon::prelude::*;
use serde::Serialize;
use shared::camera::primary_direction;
use shared::features::Variant;
use shared::glam::Vec3;
use shared::layout::{RayQuery, RayResult, NO_HIT, RAY_ALPHA_MASKS, RAY_ANY_HIT, RAY_SHORT_STACK, RAY_WIDE_BVH};
use shared::material::sample as sample_bsdf;
use shared::numerics::offset_ray_origin;
use shared::raycast::cast_ray;
use shared::rng::{Sampler, SAMPLER_INDEPENDENT};
use shared::triangle::{hit_point, unit_normal, RayShear};
use shared::vecmath::dot;
use shared::wide_packet::PACKET;
use std::time::Instant;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum RayKind {
    Primary,
    Ao,
    Diffuse,
}

/// Length of ambient-occlusion rays as a fraction of the scene box's diagonal.
pub const AO_LENGTH: f32 = 0.1;

/// The rays of one kind for the view in `s`: `per_pixel` camera rays a pixel, one after another
/// (through its centre when 1, else through uniformly jittered points: the order of a wavefront
/// integrator that keeps a pixel's samples in adjacent lanes, as Mitsuba's does); AO and diffuse
/// rays start at the camera rays' hits (offset off the surface, on the camera's side).
pub fn make_rays(
    c: &Compiled,
    s: &RenderSettings,
    kind: RayKind,
    traversal: Traversal,
    per_pixel: u32,
) -> Result<Vec<RayQuery>> {
    let p = c.params(s, 0, 1)?;
    let flags = match traversal {
        Traversal::Short => RAY_SHORT_STACK,
        Traversal::Wide => {
            c.wide_bvh();
            RAY_WIDE_BVH
        }
        _ => 0,
    };
    let flags = flags | if c.alpha_masks { RAY_ALPHA_MASKS } else { 0 };
    let eye = crate::scene::local_frame::point_to_local(s.camera.eye, c.origin);
    let width = s.width;
    let camera: Vec<RayQuery> = (0..s.height)
        .flat_map(|y| (0..width).flat_map(move |x| (0..per_pixel).map(move |k| (x, y, k))))
        .map(|(x, y, k)| {
            let (jx, jy) = if per_pixel == 1 {
                (0.5, 0.5)
            } else {
                Sampler::new(SAMPLER_INDEPENDENT, y * width + x, k, 0x1e7).next_2d()
            };
            query(eye, primary_direction(&p, x as f32 + jx, y as f32 + jy), f32::MAX, flags)
        })
        .collect();
    if kind == RayKind::Primary {
        return Ok(camera);
    }
    let params = c.bounds_params();
    let scene = c.view(&params);
    let diagonal = (c.bounds_max - c.bounds_min).length();
    let out = camera
        .par_iter()
        .enumerate()
        .filter_map(|(i, q)| {
            let hit = cast_ray(&scene, q);
            if hit.triangle == NO_HIT {
                return None;
            }
            let tri = &scene.triangles[hit.triangle as usize];
            let d = Vec3::new(q.dir.x, q.dir.y, q.dir.z);
            // The hit again, for its barycentrics: the point and its error bound come from them.
            let h = RayShear::new(eye, d).intersect(tri, 0.0, f32::MAX)?;
            let surface = hit_point(tri, &h);
            let n = unit_normal(tri);
            let n = if dot(n, d) < 0.0 { n } else { -n };
            let (u1, u2) = Sampler::new(SAMPLER_INDEPENDENT, i as u32, 0, 0x5eed).next_2d();
            let wi = sample_bsdf(
                Variant::GENERIC_SPEC,
                &c.scene.materials[c.scene.info[hit.triangle as usize].material as usize],
                &c.scene.textures,
                n,
                -d.normalize(),
                true,
                u1,
                u2,
                0.5,
            )
            .wi;
            let o = offset_ray_origin(surface.p, surface.error, n);
            Some(match kind {
                RayKind::Ao => query(o, wi, AO_LENGTH * diagonal, flags | RAY_ANY_HIT),
                _ => query(o, wi, f32::MAX, flags),
            })
        })
        .collect();
    Ok(out)
}

fn query(o: Vec3, d: Vec3, t_max: f32, flags: u32) -> RayQuery {
    RayQuery { origin: o.extend(0.0), dir: d.extend(0.0), t_max, flags, _pad: [0; 2] }
}

#[derive(Clone, Debug, Serialize)]
pub struct Throughput {
    pub kind: RayKind,
    pub rays: usize,
    pub hits: usize,
    pub seconds: f64,
    pub mrays_per_s: f64,
    pub nodes_per_ray: f64,
    pub tests_per_ray: f64,
    pub restarts_per_ray: f64,
}

/// Casts `rays` `repeats` times (after one warm-up) and keeps the fastest run. With `packets`
/// the CPU casts runs of `PACKET` consecutive rays as one packet (`shared::wide_packet`; rays
/// for the wide BVH only, others one by one).
pub fn measure(
    c: &Compiled,
    gpu: Option<&Gpu>,
    kind: RayKind,
    rays: &[RayQuery],
    repeats: usize,
    packets: bool,
) -> Result<(Throughput, Vec<RayResult>)> {
    if rays.is_empty() {
        bail!("no {kind:?} rays: the camera sees no geometry");
    }
    let params = c.bounds_params();
    let scene = c.view(&params);
    let isa = crate::render::cpu::Isa::detect();
    let cast = crate::render::cpu::cast_fn(isa);
    let cast_packet = crate::render::cpu::cast_packet_fn(isa);
    let mut best = f64::INFINITY;
    let mut results = Vec::new();
    for run in 0..=repeats {
        let (r, secs) = match gpu {
            Some(g) => g.cast_timed(c, rays)?,
            None => {
                let t = Instant::now();
                let r: Vec<RayResult> = if packets {
                    let mut r = vec![RayResult::default(); rays.len()];
                    r.par_chunks_mut(PACKET).zip(rays.par_chunks(PACKET)).for_each(|(r, q)| cast_packet(&scene, q, r));
                    r
                } else {
                    rays.par_iter().map(|q| cast(&scene, q)).collect()
                };
                (r, t.elapsed().as_secs_f64())
            }
        };
        if run > 0 {
            best = best.min(secs);
        }
        results = r;
    }
    let n = rays.len() as f64;
    let sum = |f: &dyn Fn(&RayResult) -> u32| results.iter().map(|r| f(r) as f64).sum::<f64>() / n;
    let t = Throughput {
        kind,
        rays: rays.len(),
        hits: results.iter().filter(|r| r.triangle != NO_HIT).count(),
        seconds: best,
        mrays_per_s: n / best / 1e6,
        nodes_per_ray: sum(&|r| r.nodes),
        tests_per_ray: sum(&|r| r.tests),
        restarts_per_ray: sum(&|r| r.restarts),
    };
    Ok((t, results))
}

/// The ideal rate of rays doing `nodes_per_ray` node steps and `tests_per_ray` triangle tests:
/// the rate of coherent primary rays on the same device, scaled by the SAH's own measure of the
/// work, K_T per node step and K_I per triangle test (`BuildSettings`). Aila & Laine's simulated
/// upper bound assumes ideal SIMD and memory behaviour; this is our measurable stand-in, the rate
/// every kind would reach if it did its work as efficiently as primary rays do.
pub fn ideal_mrays_per_s(
    primary: &Throughput,
    nodes_per_ray: f64,
    tests_per_ray: f64,
    traversal_cost: f64,
    intersection_cost: f64,
) -> f64 {
    let work = |n: f64, t: f64| traversal_cost * n + intersection_cost * t;
    primary.mrays_per_s * work(primary.nodes_per_ray, primary.tests_per_ray)
        / work(nodes_per_ray, tests_per_ray).max(f64::MIN_POSITIVE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ideal_rate_scales_the_primary_rate_by_sah_work() {
        let primary = Throughput {
            kind: RayKind::Primary,
            rays: 1,
            hits: 1,
            seconds: 1.0,
            mrays_per_s: 10.0,
            nodes_per_ray: 20.0,
            tests_per_ray: 3.0,
            restarts_per_ray: 0.0,
        };
        // Same work: same rate. Twice the work (in K_T·nodes + K_I·tests): half the rate.
        assert!((ideal_mrays_per_s(&primary, 20.0, 3.0, 15.0, 20.0) - 10.0).abs() < 1e-12);
        let twice = ideal_mrays_per_s(&primary, 40.0, 6.0, 15.0, 20.0);
        assert!((twice - 5.0).abs() < 1e-12);
        // A triangle test costs K_I / K_T node steps.
        let a = ideal_mrays_per_s(&primary, 20.0 + 20.0, 3.0, 15.0, 20.0);
        let b = ideal_mrays_per_s(&primary, 20.0, 3.0 + 15.0, 15.0, 20.0);
        assert!((a - b).abs() < 1e-12);
    }
}
