//! The single-source core of kdtrace: everything that runs per ray or per sample.
//!
//! This crate is `no_std` and compiles both natively (the CPU reference renderer in `host`) and to
//! SPIR-V through rust-gpu (the compute kernel in `kernel`). Both call the very same functions, so the
//! GPU image can be checked against the CPU image pixel by pixel.
//!
//! Rules that keep the two devices bit-identical where Vulkan allows it (see
//! `../shared/docs/rust-gpu-notes.md`): only `+ − × ÷ sqrt` and comparisons on floats; our own
//! polynomial sin/cos (`trig`); finiteness tested by bit pattern (`numerics`); no expression of the
//! form `1 - a - b` that the SPIR-V optimiser may reassociate.
#![cfg_attr(not(test), no_std)]
// The CPU's eight-lane leaf test (`triangle::RayShear::intersect_block`) uses `core::simd`
// (the pinned nightly that rust-gpu needs has it); SPIR-V builds never see it.
// `lanes` takes its square root from `core::intrinsics::simd` (`std::simd`'s `StdFloat` is not in
// `core`).
#![cfg_attr(not(target_arch = "spirv"), feature(portable_simd, core_intrinsics))]
#![cfg_attr(not(target_arch = "spirv"), allow(internal_features))]

pub use spirv_std::glam;

pub mod camera;
pub mod connection;
pub mod environment;
pub mod exp;
pub mod features;
pub mod integrator;
pub mod kdtree;
#[cfg(not(target_arch = "spirv"))]
pub mod lanes;
pub mod layout;
pub mod light_sample;
pub mod material;
pub mod numerics;
pub mod punctual;
pub mod raycast;
pub mod record;
pub mod rng;
pub mod sampling;
pub mod scene;
pub mod shadow;
pub mod short_stack;
pub mod sobol;
pub mod surface;
pub mod texture;
pub mod triangle;
pub mod trig;
pub mod vecmath;
#[cfg(not(target_arch = "spirv"))]
pub mod wide_bvh;
#[cfg(not(target_arch = "spirv"))]
pub mod wide_packet;
