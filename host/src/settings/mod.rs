//! Render settings: what a render needs besides the scene (image size, sampling, camera,
//! traversal), their built-in defaults and their limits, each defined once here. `scene` holds
//! the optional form a scene file, a `.kdc` and the command line state, and how it resolves;
//! `camera` the look-at camera.
pub mod camera;
pub mod scene;

use anyhow::{bail, Result};
use camera::Camera;
use shared::glam::Vec3;
use shared::rng::{SAMPLER_INDEPENDENT, SAMPLER_SOBOL};

pub use scene::SceneSettings;

/// Image width and height when neither the command line nor the scene sets them.
pub const DEFAULT_WIDTH: u32 = 512;
pub const DEFAULT_HEIGHT: u32 = 512;
pub const DEFAULT_SPP: u32 = 64;
/// Indirect bounces by default (Mitsuba's `max_depth` 8).
pub const DEFAULT_BOUNCES: u32 = 6;
pub const DEFAULT_SEED: u32 = 0;
/// Bounce from which Russian roulette may end a path (Mitsuba's `rr_depth`).
pub const RR_START: u32 = 5;
/// Largest image side accepted: beyond it, buffers or counters overflow.
pub const MAX_SIDE: u32 = 16384;
/// Most samples per pixel accepted (also what a time-limited render without an spp may reach).
pub const MAX_SPP: u32 = 1 << 20;
/// Most indirect bounces accepted.
pub const MAX_BOUNCES: u32 = 1024;

/// Which acceleration structure and traversal renders: the k-d tree with a full or a short
/// stack, or on the CPU path the eight-wide BVH. All return the hit that testing every triangle
/// returns; they differ in speed, and the traversal statistics count their own nodes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Traversal {
    /// The fastest for the device: the wide BVH on the CPU path, the k-d tree's full stack on
    /// lavapipe (faster there than the short one; BENCHMARKS.md), its short stack on GPUs, whose
    /// threads hold far less fast memory.
    #[default]
    Auto,
    /// A stack of `shared::short_stack::SHORT_STACK` entries with restart (Horn et al. 2007).
    Short,
    /// A stack as deep as the tree.
    Full,
    /// The CPU path's eight-wide BVH instead of the k-d tree (`shared::wide_bvh`).
    Wide,
}

impl Traversal {
    /// `Auto` made concrete for the k-d tree on an adapter that is (`cpu`) or is not a CPU
    /// (and for a CPU-path tool that follows k-d nodes: the debugger).
    pub fn resolve(self, cpu: bool) -> Traversal {
        match self {
            Traversal::Auto if cpu => Traversal::Full,
            Traversal::Auto => Traversal::Short,
            t => t,
        }
    }

    /// `Auto` made concrete for the CPU path: the wide BVH.
    pub fn for_cpu_path(self) -> Traversal {
        match self {
            Traversal::Auto => Traversal::Wide,
            t => t,
        }
    }

    /// `Auto` made concrete for a wgpu adapter, which has no wide BVH.
    pub fn for_adapter(self, cpu: bool) -> anyhow::Result<Traversal> {
        self.check_for_adapter()?;
        Ok(self.resolve(cpu))
    }

    /// Refuses the wide BVH for a wgpu adapter.
    pub fn check_for_adapter(self) -> anyhow::Result<()> {
        if self == Traversal::Wide {
            anyhow::bail!("--traversal wide is the CPU path's BVH; a GPU traverses the k-d tree (full or short)");
        }
        Ok(())
    }
}

/// How a pixel's samples are placed (the same numbers on the CPU and the GPU).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SamplerKind {
    /// Shuffled Owen-scrambled Sobol points, stratified per pixel and per dimension set for the
    /// film and the first two vertices (Burley 2020; `shared::sobol`, `rng::SOBOL_SETS`): the
    /// same mean, lower error at equal samples.
    #[default]
    Sobol,
    /// Independent uniforms: each a hash of (pixel, sample, set, seed).
    Independent,
}

impl SamplerKind {
    pub fn tag(self) -> u32 {
        match self {
            SamplerKind::Sobol => SAMPLER_SOBOL,
            SamplerKind::Independent => SAMPLER_INDEPENDENT,
        }
    }
}

/// Whether light subpaths connect to the eye vertices (`shared::connection`): a third way of
/// making each path, which lowers the noise of light that arrives after two or more diffuse
/// bounces. It applies to scenes of Lambertian surfaces with flat normals lit by emitting
/// triangles (`shared::features::connection_applies`); other scenes render as without it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Connect {
    /// Where the scene allows it and the light mostly arrives after a bounce: fewer than half
    /// of the camera's first hits see the point they sample on a light
    /// (`render::features::seen_light_share`). The default.
    #[default]
    Auto,
    /// Where the scene allows it.
    On,
    /// Path tracing alone.
    Off,
}

/// How the GPU spreads pixels over invocations (the CPU always uses rayon over tiles).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Dispatch {
    /// One invocation per pixel.
    #[default]
    Plain,
    /// A fixed grid of workgroups pulling pixel batches from an atomic counter (Aila & Laine 2009).
    Persistent,
}

/// What the image holds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Aov {
    /// Radiance (the render).
    #[default]
    Radiance,
    /// The camera ray's traversal work: nodes visited (R), triangles tested (G), restarts (B).
    Cost,
    /// The first hit's albedo (a conductor's reflectance at normal incidence, glass white).
    Albedo,
    /// The first hit's shading normal, turned toward the camera (EXR: −1..1; PNG: 0.5 + 0.5·n,
    /// sRGB-encoded as every PNG kdtrace writes).
    Normal,
}

/// How adaptive sampling uses its pilot samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AdaptiveMode {
    /// After `min_spp` pilot samples everywhere, each pixel's budget is fixed from its
    /// neighbours' pilot samples alone, so it does not depend on the pixel's own samples, which
    /// all stay in its mean (unbiased).
    #[default]
    Pilot,
    /// After each round the budgets are recomputed from every sample so far, the pixel's own
    /// included; the pixels below theirs go on (biased: a pixel that happens to look converged
    /// stops early; README states the bias measured).
    AsYouGo,
}

/// Adaptive sampling: every pixel gets `min_spp` samples, then as many more (up to `spp`) as the
/// image's estimated relative error needs to fall to `threshold`, most where the noise is.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Adaptive {
    /// Target relative RMS error of the image (per channel, over √(mean² + 0.01), the form of
    /// `compare`'s relMSE): relMSE ≈ threshold², so 0.03 aims at relMSE 1e-3.
    pub threshold: f32,
    pub min_spp: u32,
    pub mode: AdaptiveMode,
}

/// Pilot samples per pixel by default.
pub const DEFAULT_MIN_SPP: u32 = 16;

#[derive(Clone, Copy, Debug)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    /// Indirect bounces; 0 = direct light only.
    pub max_bounces: u32,
    pub seed: u32,
    pub sampler: SamplerKind,
    /// Light subpaths connected to the eye vertices where the scene allows.
    pub connect: Connect,
    /// Bounce from which Russian roulette may end a path (Mitsuba's `rr_depth`).
    pub rr_start: u32,
    pub environment: Vec3,
    pub camera: Camera,
    pub traversal: Traversal,
    pub dispatch: Dispatch,
    pub aov: Aov,
    /// Stop after this many seconds, between passes of whole samples; `spp` is then the most.
    pub time_limit_s: Option<f64>,
    /// Render with the integrator's variant for the scene's feature set (`render::features`);
    /// off, the generic code, which gives the same image bit for bit.
    pub specialize: bool,
    /// Adaptive sampling; `None` gives every pixel `spp` samples.
    pub adaptive: Option<Adaptive>,
    /// The CPU's connections draw their light vertices from a pool of light subpaths shared by
    /// all pixels (`shared::connection::connect_pooled`); off, each sample traces its own, as
    /// the GPU does (its images equal the GPU's bit for bit on lavapipe).
    pub light_pool: bool,
}

impl RenderSettings {
    /// The built-in defaults (the `DEFAULT_*` constants, Russian roulette from `RR_START`, black
    /// environment) seen through `camera`.
    pub fn with_camera(camera: Camera) -> Self {
        Self {
            width: DEFAULT_WIDTH,
            height: DEFAULT_HEIGHT,
            spp: DEFAULT_SPP,
            max_bounces: DEFAULT_BOUNCES,
            seed: DEFAULT_SEED,
            sampler: SamplerKind::default(),
            connect: Connect::default(),
            rr_start: RR_START,
            environment: Vec3::ZERO,
            camera,
            traversal: Traversal::default(),
            dispatch: Dispatch::default(),
            aov: Aov::default(),
            time_limit_s: None,
            specialize: true,
            adaptive: None,
            light_pool: true,
        }
    }

    pub fn check(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 || self.width > MAX_SIDE || self.height > MAX_SIDE {
            bail!("resolution {}x{} must be within 1..={MAX_SIDE} on each side", self.width, self.height);
        }
        if self.spp == 0 || self.spp > MAX_SPP {
            bail!("spp {} must be within 1..={MAX_SPP}", self.spp);
        }
        if self.max_bounces > MAX_BOUNCES {
            bail!("bounces {} must be at most {MAX_BOUNCES}", self.max_bounces);
        }
        if let Some(a) = self.adaptive {
            if !(a.threshold.is_finite() && a.threshold > 0.0) {
                bail!("adaptive threshold {} must be a positive number", a.threshold);
            }
            if a.min_spp < 2 || a.min_spp > self.spp {
                bail!(
                    "min spp {} must be at least 2 (a variance needs two samples) and at most spp {}",
                    a.min_spp,
                    self.spp
                );
            }
            if self.aov != Aov::Radiance {
                bail!("adaptive sampling estimates radiance error: it does not apply to --aov {:?}", self.aov);
            }
        }
        Ok(())
    }

    pub fn aspect(&self) -> f32 {
        self.width as f32 / self.height as f32
    }
}
