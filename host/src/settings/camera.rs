//! Camera setup on the host: look-at and field of view into the `RenderParams` basis, and the
//! default framing of a scene's bounding box from +Z.
//!
//! Positions are world coordinates in f64, like the scene's vertices: at survey coordinates an
//! f32 eye would sit up to a quarter unit off, and an f32 view direction between two such
//! points would swing with it. The basis is computed in f64 and rounded once.
use anyhow::{bail, Result};
use shared::glam::{DVec3, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: DVec3,
    pub target: DVec3,
    pub up: DVec3,
    /// Vertical field of view in degrees.
    pub fov_deg: f32,
}

/// The Cornell box's published lens: 35 mm focal length over a 25 mm film, 2·atan(12.5/35).
pub const DEFAULT_FOV_DEG: f32 = 39.307_6;

impl Camera {
    /// Looks down −Z at the box so that its front face (the +Z side) fills the frame.
    pub fn frame_bounds(lo: DVec3, hi: DVec3, aspect: f32) -> Self {
        let fov_deg = DEFAULT_FOV_DEG;
        let tan_half = ((fov_deg as f64).to_radians() * 0.5).tan();
        let center = 0.5 * (lo + hi);
        let half = 0.5 * (hi - lo);
        let fit = half.y.max(half.x / aspect as f64).max(1e-6);
        let distance = fit / tan_half;
        let eye = DVec3::new(center.x, center.y, hi.z + distance);
        Self { eye, target: center, up: DVec3::Y, fov_deg }
    }

    /// The orthonormal camera basis scaled for `RenderParams`: (right·tan·aspect, up·tan, forward).
    pub fn basis(&self, aspect: f32) -> Result<(Vec3, Vec3, Vec3)> {
        let forward = self.target - self.eye;
        if !(forward.length() > 0.0) || !forward.is_finite() {
            bail!("camera: eye and target must differ and be finite");
        }
        let forward = forward.normalize();
        let right = forward.cross(self.up);
        if !(right.length() > 1e-6) {
            bail!("camera: up vector is parallel to the view direction");
        }
        if !(self.fov_deg > 0.0 && self.fov_deg < 180.0) {
            bail!("camera: field of view {} must be in (0, 180) degrees", self.fov_deg);
        }
        let right = right.normalize();
        let up = right.cross(forward);
        let tan_half = ((self.fov_deg as f64).to_radians() * 0.5).tan();
        Ok(((right * (tan_half * aspect as f64)).as_vec3(), (up * tan_half).as_vec3(), forward.as_vec3()))
    }
}
