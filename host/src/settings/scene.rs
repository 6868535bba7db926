//! What a scene says about how to render it (image size, sampling, camera, environment), every
//! item optional, and how it resolves: an explicit command-line flag wins over the scene file,
//! which wins over the built-in defaults (`settings::DEFAULT_*`, the camera framing the scene's
//! box from +Z, black environment).
//!
//! The same struct comes from a TOML scene file, is stored (as JSON) in a compiled `.kdc` scene,
//! and is built from the CLI flags, so the three agree by construction.
use crate::settings::camera::Camera;
use crate::settings::{
    Aov, Connect, Dispatch, RenderSettings, SamplerKind, Traversal, DEFAULT_BOUNCES, DEFAULT_HEIGHT, DEFAULT_SEED,
    DEFAULT_SPP, DEFAULT_WIDTH, MAX_SPP, RR_START,
};
use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};
use shared::glam::{DVec3, Vec3};

/// Every item is optional; the same struct is the command line's image options (`clap`), the
/// scene file's settings and what a `.kdc` stores (`serde`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, clap::Args)]
#[serde(deny_unknown_fields)]
pub struct SceneSettings {
    /// [scene file, else 512]
    #[arg(long)]
    pub width: Option<u32>,
    /// [scene file, else 512]
    #[arg(long)]
    pub height: Option<u32>,
    /// Samples per pixel [scene file, else 64; with a time limit, the most].
    #[arg(long)]
    pub spp: Option<u32>,
    /// Indirect bounces, 0 = direct light only [scene file, else 6].
    #[arg(long)]
    pub bounces: Option<u32>,
    /// [scene file, else 0]
    #[arg(long)]
    pub seed: Option<u32>,
    /// Sample placement: shuffled Owen-scrambled Sobol points, or independent uniforms [scene
    /// file, else sobol].
    #[arg(long, value_enum)]
    pub sampler: Option<SamplerKind>,
    /// Connect a light subpath to every eye vertex where the scene allows it (Lambertian
    /// surfaces, flat normals, emitting triangles): less noise in indirect light, a shadow ray
    /// more per vertex; `auto` only where most of what the camera sees is not lit directly
    /// [scene file, else auto].
    #[arg(long, value_enum)]
    pub connect: Option<Connect>,
    /// Stop after SEC seconds, between passes of whole samples (every pixel gets the same
    /// number); the spp reached is reported. Without an spp it renders as many samples as fit
    /// (up to 2^20) [scene file, else none].
    #[arg(long = "time-limit", value_name = "SEC")]
    pub time_limit_s: Option<f64>,
    /// Camera position x,y,z in world coordinates, f64 like the scene's vertices (default: frame
    /// the scene's box from +Z).
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true, value_name = "X,Y,Z")]
    pub eye: Option<[f64; 3]>,
    /// The point the camera looks at, x,y,z [default: the scene box's centre].
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true, value_name = "X,Y,Z")]
    pub target: Option<[f64; 3]>,
    /// The camera's up direction, x,y,z [default: +Y].
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true, value_name = "X,Y,Z")]
    pub up: Option<[f64; 3]>,
    /// Vertical field of view in degrees [scene file, else 39.3076].
    #[arg(long = "fov")]
    pub fov_deg: Option<f32>,
    /// Radiance of rays that leave the scene, linear r,g,b [scene file, else black]. On the
    /// command line `--environment` (`cli::args::ImageArgs`) also takes an environment map file.
    #[arg(skip)]
    pub environment: Option<[f32; 3]>,
}

impl SceneSettings {
    /// `self` with every item that `flags` sets replaced by the flag's value. Written once for
    /// every item: both sides as TOML tables (unset items are absent), the flags' entries over
    /// the scene's. TOML keeps u32 and f64 values exactly.
    pub fn overridden_by(&self, flags: &SceneSettings) -> SceneSettings {
        let table = |s: &SceneSettings| toml::Table::try_from(s).expect("scene settings are a TOML table");
        let mut merged = table(self);
        merged.extend(table(flags));
        merged.try_into().expect("merged scene settings read back")
    }

    /// The render settings for a scene whose geometry spans `bounds_min..bounds_max`, with the
    /// built-in defaults for whatever is unset. Fails on values no renderer can use.
    pub fn resolve(&self, bounds_min: DVec3, bounds_max: DVec3) -> Result<RenderSettings> {
        let width = self.width.unwrap_or(DEFAULT_WIDTH);
        let height = self.height.unwrap_or(DEFAULT_HEIGHT);
        let aspect = width.max(1) as f32 / height.max(1) as f32;
        let mut camera = Camera::frame_bounds(bounds_min, bounds_max, aspect);
        if let Some(e) = self.eye {
            camera.eye = DVec3::from(e);
        }
        if let Some(t) = self.target {
            camera.target = DVec3::from(t);
        }
        if let Some(u) = self.up {
            camera.up = DVec3::from(u);
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
            connect: self.connect.unwrap_or_default(),
            rr_start: RR_START,
            environment,
            camera,
            traversal: Traversal::default(),
            dispatch: Dispatch::default(),
            aov: Aov::default(),
            time_limit_s: self.time_limit_s,
            specialize: true,
            adaptive: None,
            light_pool: true,
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
            connect: Some(s.connect),
            time_limit_s,
            eye: Some(s.camera.eye.to_array()),
            target: Some(s.camera.target.to_array()),
            up: Some(s.camera.up.to_array()),
            fov_deg: Some(s.camera.fov_deg),
            environment: Some(s.environment.to_array()),
        }
    }
}

/// A world point or vector `x,y,z`, read in f64 like the scene's vertices.
pub fn parse_point(s: &str) -> Result<[f64; 3], String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!("expected x,y,z, got {s:?}"));
    }
    let mut v = [0.0f64; 3];
    for (slot, p) in v.iter_mut().zip(parts) {
        *slot = p.trim().parse().map_err(|_| format!("{p:?} is not a number"))?;
        if !slot.is_finite() {
            return Err(format!("{p:?} is not finite"));
        }
    }
    Ok(v)
}

/// A linear RGB colour `r,g,b`: finite, non-negative.
pub fn parse_color(s: &str) -> Result<[f32; 3], String> {
    let v = parse_point(s)?;
    if v.iter().any(|c| *c < 0.0 || *c > f32::MAX as f64) {
        return Err(format!("colour {s:?} must be non-negative"));
    }
    Ok(v.map(|c| c as f32))
}
