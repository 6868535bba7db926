//! Progressive rendering: a render driven one pass at a time by its caller, on either device.
//!
//! `cpu::progressive` and `Gpu::progressive` prepare the scene and allocate the per-pixel sums
//! once; each `pass(start, count)` then adds samples `[start, start + count)` to every pixel,
//! and `image` returns what has accumulated so far, so a caller (the web UI, `cpu::render` and
//! `Gpu::render` with their time limits and progress bars) can look at the image between passes
//! and stop at any pass. Every pixel's samples are added in sample order, whatever the split into
//! passes, so the sums equal those of one pass bit for bit. Passes follow each other: each starts
//! where the previous one ended, from sample 0, so every pixel always holds the same samples
//! (an unbiased image at any point). Adaptive sampling has its own driver (`adaptive`).
use crate::render::Rendered;
use crate::settings::MAX_SPP;
use anyhow::{bail, Result};

/// A render in progress on one device: the scene is prepared and the sums allocated once.
pub trait Progressive {
    /// Adds samples [start, start + count) of every pixel to its sums, in sample order (so any
    /// split into passes sums the same numbers in the same order as one pass: bit-identical).
    /// `start` must be the samples added so far; a pass of no samples does nothing.
    fn pass(&mut self, start: u32, count: u32) -> Result<()>;
    /// The image accumulated so far (`spp` = samples added; a GPU reads its buffers back).
    fn image(&mut self) -> Result<Rendered>;
    /// The samples per pixel added so far.
    fn spp(&self) -> u32;
    /// The device's name for reports (e.g. "cpu (2 threads)" or the adapter's name).
    fn device(&self) -> String;
}

/// Checks that a pass of `count` samples from `start` follows a render holding `done` samples
/// and stays within `MAX_SPP`.
pub(crate) fn check_pass(done: u32, start: u32, count: u32) -> Result<()> {
    if start != done {
        bail!("a progressive pass must start at the samples added so far ({done}), not at {start}");
    }
    if start.checked_add(count).is_none_or(|end| end > MAX_SPP) {
        bail!("a progressive pass of samples {start}..{start}+{count} goes past {MAX_SPP} samples per pixel");
    }
    Ok(())
}

// Both renders in progress can move to another thread (the web server runs passes in blocking
// tasks).
const _: () = {
    fn send<T: Send>() {}
    #[allow(dead_code)]
    fn both_are_send() {
        send::<crate::render::cpu::CpuProgressive<'static>>();
        send::<crate::render::gpu::GpuProgressive<'static>>();
    }
};
