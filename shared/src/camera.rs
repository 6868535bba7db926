//! Pinhole camera: vertical field of view and look-at, with a box pixel filter (uniform jitter).
//! The host turns eye/target/up/fov into `RenderParams::{eye, right, up, forward}`; this is the
//! per-sample half, using only multiplies and adds so both devices agree.
use crate::glam::Vec3;
use crate::layout::RenderParams;
use crate::vecmath::{normalize, xyz};

/// Unit direction of the camera ray through film position (x, y) in pixels, y down.
#[inline]
pub fn primary_direction(p: &RenderParams, x: f32, y: f32) -> Vec3 {
    let sx = 2.0 * x * p.inv_width - 1.0;
    let sy = 1.0 - 2.0 * y * p.inv_height;
    normalize(xyz(p.forward) + xyz(p.right) * sx + xyz(p.up) * sy)
}
