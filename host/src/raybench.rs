//! Ray-casting throughput for the three ray kinds of Aila & Laine, "Understanding the Efficiency
//! of Ray Traversal on GPUs" (HPG 2009): primary rays (coherent), ambient-occlusion rays (short,
//! any hit, from the primary hits) and diffuse-bounce rays (cosine-distributed, closest hit,
//! incoherent). No shading: only `shared::raycast::cast_ray`, on the CPU (rayon) or through the
//! ray-casting kernel.
//!
//! Alongside rays/s it reports the traversal's work per ray (nodes visited, triangles tested,
//! restarts) and an ideal rate, our stand-in for Aila & Laine's simulated upper bound: the rate
//! this device would reach if every ray setup, node step and triangle test cost what it costs
//! for coherent primary rays. The per-operation costs come from a least-squares fit over bands of
//! primary rays on the same device (`fit_costs`); measured/ideal then shows what incoherence
//! (divergence, cache misses) costs.
use crate::gpu::Gpu;
use crate::render::{Compiled, RenderSettings, Traversal};
use anyhow::{bail, Result};
use rayon::prelude::*;
use serde::Serialize;
use shared::camera::primary_direction;
use shared::glam::Vec3;
use shared::layout::{RayQuery, RayResult, NO_HIT, RAY_ANY_HIT, RAY_SHORT_STACK};
use shared::material::sample as sample_bsdf;
use shared::numerics::offset_ray_origin;
use shared::raycast::cast_ray;
use shared::rng::Sampler;
use shared::triangle::{geometric_normal, hit_point, RayShear};
use shared::vecmath::{dot, normalize};
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

/// The rays of one kind for the view in `s`: one camera ray per pixel centre; AO and diffuse rays
/// start at the camera rays' hits (offset off the surface, on the camera's side).
pub fn make_rays(c: &Compiled, s: &RenderSettings, kind: RayKind, traversal: Traversal) -> Result<Vec<RayQuery>> {
    let p = c.params(s, 0, 1)?;
    let flags = if traversal == Traversal::Short { RAY_SHORT_STACK } else { 0 };
    let eye = s.camera.eye;
    let camera: Vec<RayQuery> = (0..s.height)
        .flat_map(|y| (0..s.width).map(move |x| (x, y)))
        .map(|(x, y)| query(eye, primary_direction(&p, x as f32 + 0.5, y as f32 + 0.5), f32::MAX, flags))
        .collect();
    if kind == RayKind::Primary {
        return Ok(camera);
    }
    let params = c.bounds_params();
    let scene = c.view(&params);
    let diagonal = (c.tree.bounds_max - c.tree.bounds_min).length();
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
            let n = normalize(geometric_normal(tri));
            let n = if dot(n, d) < 0.0 { n } else { -n };
            let mut rng = Sampler::new(i as u32, 0, 0x5eed);
            let wi = sample_bsdf(&c.scene.materials[c.scene.info[hit.triangle as usize].material as usize], n, rng.next_1d(), rng.next_1d()).wi;
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

/// Casts `rays` `repeats` times (after one warm-up) and keeps the fastest run.
pub fn measure(c: &Compiled, gpu: Option<&Gpu>, kind: RayKind, rays: &[RayQuery], repeats: usize) -> Result<(Throughput, Vec<RayResult>)> {
    if rays.is_empty() {
        bail!("no {kind:?} rays: the camera sees no geometry");
    }
    let params = c.bounds_params();
    let scene = c.view(&params);
    let mut best = f64::INFINITY;
    let mut results = Vec::new();
    for run in 0..=repeats {
        let (r, secs) = match gpu {
            Some(g) => g.cast_timed(c, rays)?,
            None => {
                let t = Instant::now();
                let r: Vec<RayResult> = rays.par_iter().map(|q| cast_ray(&scene, q)).collect();
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

/// One timed batch: (rays, node steps, triangle tests, seconds).
pub type Sample = (f64, f64, f64, f64);

/// Times `bands` equal slices of `rays` (image rows, so their mix of empty sky, node steps and
/// triangle tests differs) and returns one `Sample` per slice, for `fit_costs`.
pub fn band_samples(c: &Compiled, gpu: Option<&Gpu>, rays: &[RayQuery], bands: usize, repeats: usize) -> Result<Vec<Sample>> {
    let per = rays.len().div_ceil(bands.max(1));
    let mut out = Vec::new();
    for chunk in rays.chunks(per.max(1)) {
        let (t, results) = measure(c, gpu, RayKind::Primary, chunk, repeats)?;
        let nodes = results.iter().map(|r| r.nodes as f64).sum();
        let tests = results.iter().map(|r| r.tests as f64).sum();
        out.push((chunk.len() as f64, nodes, tests, t.seconds));
    }
    Ok(out)
}

/// The cost model t = c·rays + a·nodes + b·tests (per-ray setup, node step, triangle test, at the
/// device's full parallelism) fitted by least squares to timed batches. `None` when the batches
/// cannot separate the three costs or a cost comes out negative.
pub fn fit_costs(samples: &[Sample]) -> Option<Costs> {
    // Normal equations AᵀA x = Aᵀt for rows (rays, nodes, tests), solved by Cramer's rule.
    let mut m = [[0.0f64; 3]; 3];
    let mut v = [0.0f64; 3];
    for &(r, n, k, t) in samples {
        let row = [r, n, k];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += row[i] * row[j];
            }
            v[i] += row[i] * t;
        }
    }
    let det3 = |a: [[f64; 3]; 3]| a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    let d = det3(m);
    let scale = m[0][0] * m[1][1] * m[2][2];
    if !(d.abs() > 1e-9 * scale) {
        return None;
    }
    let solve = |col: usize| {
        let mut a = m;
        for (i, row) in a.iter_mut().enumerate() {
            row[col] = v[i];
        }
        det3(a) / d
    };
    let (per_ray, per_node, per_test) = (solve(0), solve(1), solve(2));
    (per_ray >= 0.0 && per_node > 0.0 && per_test > 0.0).then_some(Costs { per_ray, per_node, per_test })
}

/// Seconds per ray, per node step and per triangle test.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Costs {
    pub per_ray: f64,
    pub per_node: f64,
    pub per_test: f64,
}

impl Costs {
    /// Mrays/s for rays doing this much work on average.
    pub fn ideal_mrays_per_s(&self, nodes_per_ray: f64, tests_per_ray: f64) -> f64 {
        1e-6 / (self.per_ray + self.per_node * nodes_per_ray + self.per_test * tests_per_ray)
    }
}

#[cfg(test)]
mod tests {
    use super::fit_costs;

    #[test]
    fn cost_fit_recovers_a_linear_model() {
        let samples: Vec<_> = (1..20)
            .map(|i| {
                let (r, n, k) = (1000.0 + (i % 3) as f64 * 100.0, i as f64 * 1e4, ((i * i) % 7) as f64 * 1e3 + 1.0);
                (r, n, k, 1e-8 * r + 2e-9 * n + 5e-9 * k)
            })
            .collect();
        let c = fit_costs(&samples).unwrap();
        assert!((c.per_ray - 1e-8).abs() < 1e-13 && (c.per_node - 2e-9).abs() < 1e-14 && (c.per_test - 5e-9).abs() < 1e-14, "{c:?}");
        assert!((c.ideal_mrays_per_s(10.0, 2.0) - 1e-6 / (1e-8 + 2e-8 + 1e-8)).abs() < 1e-6);
        // Proportional columns cannot be separated.
        assert!(fit_costs(&[(1.0, 2.0, 3.0, 1.0), (2.0, 4.0, 6.0, 2.0), (3.0, 6.0, 9.0, 3.0)]).is_none());
    }
}
