//! Options several commands share: the image options (the command line's form of
//! `SceneSettings`, plus how to render) and the k-d build settings.
use crate::kdbuild::{BuildSettings, Builder};
use crate::settings::{AdaptiveMode, Aov, Dispatch, SceneSettings, Traversal, DEFAULT_MIN_SPP};
use anyhow::Result;
use clap::{Args, ValueEnum};
use serde::Serialize;

/// Which renderer runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Device {
    Cpu,
    Gpu,
}

impl Device {
    pub fn name(self) -> &'static str {
        match self {
            Device::Cpu => "cpu",
            Device::Gpu => "gpu",
        }
    }

    /// The tree's build settings for the device that traverses it: the CPU tests leaves eight
    /// triangles at a time, a GPU thread one by one (`BuildSettings::for_gpu`).
    pub fn build_settings(self) -> BuildSettings {
        match self {
            Device::Cpu => BuildSettings::default(),
            Device::Gpu => BuildSettings::for_gpu(),
        }
    }
}

/// Image options. Each scene setting given overrides the scene file; unset ones come from the
/// scene file, then from the built-in defaults (`kdtrace::settings`).
#[derive(Args, Clone)]
pub struct ImageArgs {
    #[command(flatten)]
    pub scene: SceneSettings,
    /// glTF scenes: the camera to render, by index or name [default: the file's first perspective
    /// camera; none: frame the scene].
    #[arg(long, value_name = "NAME|INDEX")]
    pub camera: Option<String>,
    /// Radiance of rays that leave the scene: linear r,g,b, or an equirectangular environment
    /// map FILE (.exr, .hdr or .pfm; strength 1, not rotated), which replaces the scene's [scene file,
    /// else black].
    #[arg(long, value_name = "R,G,B|FILE", allow_hyphen_values = true)]
    pub environment: Option<String>,
    /// GPU adapter: the first whose name contains this (default: the first adapter).
    #[arg(long)]
    pub adapter: Option<String>,
    /// Print one JSON line to stdout instead of a progress bar.
    #[arg(long)]
    pub json: bool,
    /// Traversal: the k-d tree with a short stack with restart or a stack as deep as the tree,
    /// the CPU path's eight-wide BVH, or the fastest for the device (wide on the CPU path, full
    /// on lavapipe, short on GPUs).
    #[arg(long, value_enum, default_value_t)]
    pub traversal: Traversal,
    /// GPU work distribution: one invocation per pixel, or persistent threads.
    #[arg(long, value_enum, default_value_t)]
    pub dispatch: Dispatch,
    /// Image content: radiance, or the camera ray's traversal cost (PNG: heat map of nodes +
    /// triangle tests; EXR: nodes, tests, restarts per pixel).
    #[arg(long, value_enum, default_value_t)]
    pub aov: Aov,
    /// Run the integrator's variant for what the scene uses (on), or the generic code (off):
    /// the same image bit for bit, in different times.
    #[arg(long, value_enum, default_value_t = Switch::On)]
    pub specialize: Switch,
    /// The light subpaths for the connections (`--connect`): from a pool shared by all pixels,
    /// each eye vertex picking among several (on), or one per sample (off).
    #[arg(long, value_enum, default_value_t = Switch::On)]
    pub light_pool: Switch,
    /// Adaptive sampling to this relative RMS error of the image (per channel, over
    /// √(mean² + 0.01): relMSE ≈ THRESHOLD², so 0.03 aims at 1e-3); `--spp` is then the most a
    /// pixel gets.
    #[arg(long, value_name = "THRESHOLD")]
    pub adaptive: Option<f32>,
    /// With --adaptive: samples every pixel gets first.
    #[arg(long, value_name = "N", requires = "adaptive", default_value_t = DEFAULT_MIN_SPP)]
    pub min_spp: u32,
    /// With --adaptive: `pilot` (unbiased: after the pilot, each pixel's budget is fixed from
    /// its neighbours' samples alone) or `as-you-go` (budgets recomputed every round from all
    /// samples so far; biased, see README).
    #[arg(long, value_enum, requires = "adaptive", default_value_t)]
    pub adaptive_mode: AdaptiveMode,
}

/// A command-line on/off switch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Switch {
    On,
    Off,
}

/// k-d tree build settings; defaults in `kdbuild::BuildSettings`.
#[derive(Args, Clone)]
pub struct BuildArgs {
    /// Tree builder.
    #[arg(long, value_enum)]
    builder: Option<Builder>,
    /// SAH cost of a traversal step (K_T).
    #[arg(long)]
    traversal_cost: Option<f32>,
    /// SAH cost of a triangle test (K_I).
    #[arg(long)]
    intersection_cost: Option<f32>,
    /// Triangles one leaf test covers in the SAH (1: every triangle counts).
    #[arg(long)]
    leaf_block: Option<u32>,
    /// SAH factor λ for splits with an empty side.
    #[arg(long)]
    empty_factor: Option<f32>,
    /// Maximum tree depth (0: 8 + 1.3·log2 N).
    #[arg(long)]
    max_depth: Option<u32>,
    /// Nodes with at most this many triangles become leaves.
    #[arg(long)]
    leaf_size: Option<u32>,
    /// Splits costlier than a leaf allowed on one path.
    #[arg(long)]
    bad_refines: Option<u32>,
    /// Most triangle references per triangle in the whole tree (0: no limit).
    #[arg(long)]
    max_refs_factor: Option<f32>,
}

impl BuildArgs {
    pub fn settings(&self) -> Result<BuildSettings> {
        let d = BuildSettings::default();
        let s = BuildSettings {
            builder: self.builder.unwrap_or(d.builder),
            traversal_cost: self.traversal_cost.unwrap_or(d.traversal_cost),
            intersection_cost: self.intersection_cost.unwrap_or(d.intersection_cost),
            leaf_block: self.leaf_block.unwrap_or(d.leaf_block),
            empty_factor: self.empty_factor.unwrap_or(d.empty_factor),
            max_depth: self.max_depth.unwrap_or(d.max_depth),
            leaf_size: self.leaf_size.unwrap_or(d.leaf_size),
            bad_refines: self.bad_refines.unwrap_or(d.bad_refines),
            max_refs_factor: self.max_refs_factor.unwrap_or(d.max_refs_factor),
        };
        s.check()?;
        Ok(s)
    }
}
