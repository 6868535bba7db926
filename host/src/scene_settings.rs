//! What a scene says about how to render it (image size, sampling, camera, environment), every
//! item optional, and how it resolves: an explicit command-line flag wins over the scene file,
//! which wins over the built-in defaults (512×512, 64 spp, 6 bounces, seed 0, the camera framing
//! the scene's box from +Z, black environment).
//!
//! The same struct comes from a TOML scene file, is stored (as JSON) in a compiled `.kdc` scene,
//! and is built from the CLI flags, so the three agree by construction.
use crate::camera::Camera;
use crate::render::{Aov, Dispatch, RenderSettings, SamplerKind, Traversal, MAX_SPP};
use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};
use shared::glam::Vec3;

pub const DEFAULT_WIDTH: u32 = 512;
pub const DEFAULT_HEIGHT: u32 = 512;
pub const DEFAULT_SPP: u32 = 64;
pub const DEFAULT_BOUNCES: u32 = 6;
pub const DEFAULT_SEED: u32 = 0;
/// Bounce from which Russian roulette may end a path (Mitsuba's `rr_depth`).
pub const RR_START: u32 = 5;

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneSettings {
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub spp: Option<u32>,
    /// Indirect bounces; 0 = direct light only.
    pub bounces: Option<u32>,
    pub seed: Option<u32>,
    /// Sample placement (default Sobol).
    pub sampler: Option<SamplerKind>,
    /// Wall-clock budget in seconds: the render stops between passes of whole samples once it is
    /// spent. Without an spp it renders as many samples as fit (up to `MAX_SPP`).
    pub time_limit_s: Option<f64>,
    pub eye: Option<[f32; 3]>,
    pub target: Option<[f32; 3]>,
    pub up: Option<[f32; 3]>,
    /// Vertical field of view in degrees.
    pub fov_deg: Option<f32>,
    /// Radiance of rays that leave the scene, linear RGB.
    pub environment: Option<[f32; 3]>,
}

impl SceneSettings {
    /// `self` with every item that `flags` sets replaced by the flag's value.
    pub fn overridden_by(&self, flags: &SceneSettings) -> SceneSettings {
        SceneSettings {
            width: flags.width.or(self.width),
            height: flags.height.or(self.height),
            spp: flags.spp.or(self.spp),
            bounces: flags.bounces.or(self.bounces),
            seed: flags.seed.or(self.seed),
            sampler: flags.sampler.or(self.sampler),
            time_limit_s: flags.time_limit_s.or(self.time_limit_s),
            eye: flags.eye.or(self.eye),
            target: flags.target.or(self.target),
            up: flags.up.or(self.up),
            fov_deg: flags.fov_deg.or(self.fov_deg),
            environment: flags.environment.or(self.environment),
        }
    }

    /// The render settings for a scene whose geometry spans `bounds_min..bounds_max`, with the
    /// built-in defaults for whatever is unset. Fails on values no renderer can use.
    pub fn resolve(&self, bounds_min: Vec3, bounds_max: Vec3) -> Result<RenderSettings> {
        let width = self.width.unwrap_or(DEFAULT_WIDTH);
        let height = self.height.unwrap_or(DEFAULT_HEIGHT);
        let aspect = width.max(1) as f32 / height.max(1) as f32;
        let mut camera = Camera::frame_bounds(bounds_min, bounds_max, aspect);
        if let Some(e) = self.eye {
            camera.eye = Vec3::from(e);
        }
        if let Some(t) = self.target {
            camera.target = Vec3::from(t);
        }
        if let Some(u) = self.up {
            camera.up = Vec3::from(u);
        }
        if let Some(f) = self.fov_deg {
            camera.fov_deg = f;
        }
        let environment = Vec3::from(self.environment.unwrap_or([0.0; 3]));
        if !environment.is_finite() || environment.min_element() < 0.0 {
            bail!("environment {environment} must be finite and non-negative");
        }
        if let Some(t) = self.time_limit_s {
            if !(t.is_finite() && t > 0.0) {
                bail!("time limit {t} s must be a positive number of seconds");
            }
        }
        let s = RenderSettings {
            width,
            height,
            spp: self.spp.unwrap_or(if self.time_limit_s.is_some() { MAX_SPP } else { DEFAULT_SPP }),
            max_bounces: self.bounces.unwrap_or(DEFAULT_BOUNCES),
            seed: self.seed.unwrap_or(DEFAULT_SEED),
            sampler: self.sampler.unwrap_or_default(),
            rr_start: RR_START,
            environment,
            camera,
            traversal: Traversal::default(),
            dispatch: Dispatch::default(),
            aov: Aov::default(),
            time_limit_s: self.time_limit_s,
        };
        s.check()?;
        camera.basis(aspect)?;
        Ok(s)
    }

    /// Every item set from resolved render settings (what `export` writes).
    pub fn pinned(s: &RenderSettings, time_limit_s: Option<f64>) -> SceneSettings {
        SceneSettings {
            width: Some(s.width),
            height: Some(s.height),
            spp: Some(s.spp),
            bounces: Some(s.max_bounces),
            seed: Some(s.seed),
            sampler: Some(s.sampler),
            time_limit_s,
            eye: Some(s.camera.eye.to_array()),
            target: Some(s.camera.target.to_array()),
            up: Some(s.camera.up.to_array()),
            fov_deg: Some(s.camera.fov_deg),
            environment: Some(s.environment.to_array()),
        }
    }
}
