//! The websocket protocol of `kdtrace serve` (`/ws`): JSON text messages both ways, frames as
//! binary PNG. README.md ("Web UI and remote debugger") documents it for other clients; these
//! types are the one definition of it.
use crate::cli::Device;
use crate::settings::Aov;
use serde::{Deserialize, Serialize};

/// Messages longer than this get an `error` reply without being parsed.
pub const MAX_MESSAGE_BYTES: usize = 64 * 1024;

/// A client's request.
#[derive(Deserialize, Debug)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum ClientMessage {
    /// Start (or restart) this client's render; every field is optional and falls back to the
    /// scene's own settings, then the built-in defaults.
    Render(RenderRequest),
    /// Stop this client's render.
    Stop,
    /// Replay one sample of one pixel of the client's latest render on the CPU.
    Pixel(PixelRequest),
}

#[derive(Deserialize, Debug, Default, Clone)]
#[serde(deny_unknown_fields)]
pub struct RenderRequest {
    /// Index into the `hello` message's scene list.
    pub scene: Option<usize>,
    pub spp: Option<u32>,
    pub bounces: Option<u32>,
    pub camera: Option<CameraRequest>,
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub seed: Option<u32>,
    /// "cpu" or "gpu" (the server's `--device` when absent).
    pub device: Option<Device>,
    /// What the image shows: "radiance" (default), "cost", "albedo" or "normal".
    pub aov: Option<Aov>,
}

/// A look-at camera in world coordinates; absent fields keep the scene's.
#[derive(Deserialize, Serialize, Debug, Default, Clone, Copy)]
#[serde(deny_unknown_fields)]
pub struct CameraRequest {
    pub eye: Option<[f64; 3]>,
    pub target: Option<[f64; 3]>,
    pub up: Option<[f64; 3]>,
    /// Vertical field of view in degrees.
    pub fov: Option<f32>,
}

#[derive(Deserialize, Debug, Clone, Copy)]
#[serde(deny_unknown_fields)]
pub struct PixelRequest {
    pub x: u32,
    pub y: u32,
    #[serde(default)]
    pub sample: u32,
    /// The seed of the render whose sample is replayed (the latest render's when absent).
    pub seed: Option<u32>,
}

/// What the server says.
#[derive(Serialize, Debug)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum ServerMessage<'a> {
    /// Sent once on connecting: the scenes and what a render may ask for.
    Hello(Hello),
    /// Sent before each frame (a binary PNG message follows at once).
    Progress(Progress),
    /// The render ended: its samples are all in, or it was stopped or replaced.
    Done(Progress),
    /// A replayed sample: pixel, sample, seed, `radiance` and `vertices` (`debug::PathRecord`).
    Path {
        #[serde(flatten)]
        record: &'a crate::debug::PathRecord,
    },
    Error {
        message: String,
    },
}

#[derive(Serialize, Debug, Clone)]
pub struct Hello {
    pub version: u32,
    pub scenes: Vec<SceneInfo>,
    /// The devices this server renders on; `device` is the default.
    pub devices: Vec<Device>,
    pub device: Device,
    pub limits: Limits,
}

#[derive(Serialize, Debug, Clone)]
pub struct SceneInfo {
    pub index: usize,
    pub name: String,
    pub triangles: usize,
    pub lights: usize,
    /// The k-d tree's node count and depth.
    pub nodes: usize,
    pub tree_depth: u32,
    /// The scene's own settings, resolved: what a `render` without fields renders.
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub bounces: u32,
    pub seed: u32,
    pub camera: CameraInfo,
    /// The scene's bounds in world coordinates, for camera controls.
    pub bounds_min: [f64; 3],
    pub bounds_max: [f64; 3],
    /// What loading found amiss (the command line's warnings), and whether nothing lights the
    /// scene: the page shows them beside the image.
    pub warnings: Vec<String>,
}

#[derive(Serialize, Debug, Clone, Copy)]
pub struct CameraInfo {
    pub eye: [f64; 3],
    pub target: [f64; 3],
    pub up: [f64; 3],
    pub fov: f32,
}

#[derive(Serialize, Debug, Clone, Copy)]
pub struct Limits {
    pub max_message_bytes: usize,
    pub max_pixels: u64,
    pub max_spp: u32,
    pub max_bounces: u32,
}

#[derive(Serialize, Debug, Clone)]
pub struct Progress {
    /// Samples per pixel rendered so far, of `target`.
    pub spp: u32,
    pub target: u32,
    /// Samples (all pixels) per second of render time so far, and that time.
    pub samples_per_s: f64,
    pub elapsed_s: f64,
    pub scene: usize,
    pub width: u32,
    pub height: u32,
    pub device: String,
}
