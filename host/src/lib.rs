//! kdtrace host: scene input (OBJ, TOML scene files, placement and the local frame, compiled
//! `.kdc` scenes), render settings, k-d tree construction, the CPU reference renderer and the
//! wgpu runner for the rust-gpu kernel, image output and error metrics, the replay of one pixel
//! sample for debugging, and the command line.
//!
//! Dependencies run one way: `cli` → `debug` → `render` → `scene`, `kdbuild`, `image` → `settings`.
// The k-d builder compares sixteen events at once (`kdbuild::sah`), as the shared crate's leaf
// test tests eight triangles; the pinned nightly has `core::simd`.
#![feature(portable_simd)]
pub mod bvh;
pub mod cli;
pub mod debug;
pub mod files;
pub mod image;
pub mod kdbuild;
pub mod render;
pub mod scene;
pub mod serve;
pub mod settings;

pub use render::load::{compile, load, Loaded, SceneKind};
