//! Debugging one pixel: replaying one of its samples on the CPU through the integrator the
//! renderers run (`shared::integrator::trace_sample_recorded`, with a recorder that keeps every
//! event), and projecting world points into the image.
//!
//! The replay is exact: it runs the same function on the same scene layout with the same
//! parameters, seed, pixel and sample as `render::cpu`, so its `radiance` is, bit for bit, what
//! a CPU render adds to that pixel's sum for that sample (`tests/pixel_replay.rs`). It runs the
//! variant of the render's feature bits as a run-time `Variant`, not the render's monomorph:
//! specialisation changes no value (`tests/specialisation.rs`), and a recorder needs one
//! monomorph of its own anyway.
mod record;

pub use record::{
    material_kind_name, BsdfRecord, ConnectionRecord, EmissionRecord, EscapeRecord, LightRecord, PathRecord,
    RouletteRecord, ShadowRayRecord, TraversalRecord, VertexRecord, MAX_RECORDED_PER_RAY,
};

use crate::render::{features, Compiled};
use crate::settings::RenderSettings;
use anyhow::{bail, Result};
use record::{arr, Collector};
use shared::features::Variant;
use shared::glam::DVec3;
use shared::integrator::trace_sample_recorded;
use shared::layout::AOV_NORMAL;
use shared::numerics::sanitize;

/// Replays sample `sample` of pixel (x, y) of the render `s` of `c` on the CPU and records the
/// path: every vertex's surface, emission, light sample and shadow ray, BSDF sample, throughput
/// and roulette, and the k-d nodes and triangles each ray went through. Errors for settings a
/// render would refuse and for a pixel outside the image.
pub fn replay(c: &Compiled, s: &RenderSettings, x: u32, y: u32, sample: u32) -> Result<PathRecord> {
    s.check()?;
    if x >= s.width || y >= s.height {
        bail!("pixel ({x}, {y}) lies outside the {}x{} image", s.width, s.height);
    }
    // On the k-d tree, whose nodes the record lists: `auto` is the full stack, as on lavapipe.
    // The wide BVH returns the same hits (`shared::wide_bvh`) but names no k-d nodes.
    let s = &RenderSettings { traversal: s.traversal.resolve(true), ..*s };
    let params = c.params(s, sample, 1)?;
    let scene = c.view(&params);
    // The pool the render's sample drew from (`render::light_pool`).
    let (pool, first) = crate::render::light_pool::pool_of(&scene, &params, sample, sample + 1);
    let scene = crate::render::light_pool::view(&scene, &pool, first);
    let v = Variant::new(features::variant_bits(c, s), &params);
    let project = |p: DVec3| project(s, p);
    let mut rec = Collector::new(&c.tree().nodes, &c.tree().indices, c.origin, &project);
    let r = trace_sample_recorded(&scene, &params, v, x, y, sample, &mut rec);
    // What `shared::integrator::render_samples` adds to the pixel's sum.
    let (l, zeroed) = sanitize(r.radiance, params.aov == AOV_NORMAL);
    Ok(PathRecord {
        x,
        y,
        sample,
        seed: s.seed,
        radiance: arr(l),
        zeroed,
        raw_radiance: arr(r.radiance),
        end: rec.end,
        camera_origin: rec.camera_origin,
        camera_direction: rec.camera_direction,
        vertices: rec.vertices,
        escaped: rec.escaped,
    })
}

/// Where world point `p` appears in the image of render `s`: continuous pixel coordinates (x
/// right, y down; pixel (i, j) covers [i, i + 1) × [j, j + 1)), the inverse of
/// `shared::camera::primary_direction` with the render's own (f32) camera basis; `None` for a
/// point behind the camera or in its plane, or a camera the render would refuse. The point may
/// lie outside the image.
pub fn project(s: &RenderSettings, p: DVec3) -> Option<[f64; 2]> {
    let (right, up, forward) = s.camera.basis(s.aspect()).ok()?;
    let (r, u, f) = (right.as_dvec3(), up.as_dvec3(), forward.as_dvec3());
    let d = p - s.camera.eye;
    // d = a·forward + b·right + c·up, by Cramer's rule; the film position is (b/a, c/a).
    let det = f.dot(r.cross(u));
    let a = d.dot(r.cross(u)) / det;
    if !(a > 0.0) {
        return None;
    }
    let b = f.dot(d.cross(u)) / det;
    let c = f.dot(r.cross(d)) / det;
    let (sx, sy) = (b / a, c / a);
    let px = [(sx + 1.0) * 0.5 * s.width as f64, (1.0 - sy) * 0.5 * s.height as f64];
    px.iter().all(|c| c.is_finite()).then_some(px)
}
