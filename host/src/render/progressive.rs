//! Progressive rendering: a render driven one pass at a time by its caller, on either device.
//!
//! `cpu::progressive` and `Gpu::progressive` prepare the scene and allocate the per-pixel sums
//! once; each `pass(start, count)` then adds samples `[start, start + count)` to every pixel,
//! and `image` returns what has accumulated so far, so a caller (the web UI, `cpu::render` and
//! `Gpu::render` with their time limits and progress bars) can look at the image between passes
//! and stop at any pass. The samples go into fixed blocks whose sums are folded in a fixed order
//! (`blocks`): passes are cut at block boundaries, each block is added from zero on the device
//! and the completed blocks go into the fold, so any split into passes gives the sums of one
//! pass bit for bit, and equals partial renders merged or several devices at once. Passes follow
//! each other: each starts where the previous one ended, from sample 0 (or from the block where
//! a partial render starts, `start_at`), so every pixel always holds the same samples (an
//! unbiased image at any point). Adaptive sampling has its own driver (`adaptive`).
use crate::render::blocks::{block_of, Fold, Node, NodeId, Sums, BLOCK_SAMPLES};
use crate::render::Rendered;
use crate::settings::MAX_SPP;
use anyhow::{bail, Result};

/// A render in progress on one device: the scene is prepared and the sums allocated once.
pub trait Progressive {
    /// Adds samples [start, start + count) of every pixel to its sums: each block's in sample
    /// order from zero, completed blocks into the fold (`blocks`), so any split into passes
    /// gives the bits of one pass. `start` must be the samples added so far; a pass of no
    /// samples does nothing.
    fn pass(&mut self, start: u32, count: u32) -> Result<()>;
    /// The image accumulated so far (`spp` = samples added; a GPU reads its buffers back): the
    /// fold of the completed blocks with the running one as the last, so a render that stops
    /// here equals `image` of one pass of the same samples.
    fn image(&mut self) -> Result<Rendered>;
    /// The samples per pixel added so far.
    fn spp(&self) -> u32;
    /// The device's name for reports (e.g. "cpu (2 threads)" or the adapter's name).
    fn device(&self) -> String;
    /// Before any pass: makes the render start at sample `start`, a multiple of
    /// `BLOCK_SAMPLES` (a partial render of samples `[start, …)`).
    fn start_at(&mut self, start: u32) -> Result<()>;
    /// The fold's nodes so far, the running block as the last one (what a partial file stores).
    fn nodes(&mut self) -> Result<Vec<Node>>;
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

/// A device's running sums, the one block being added: what `Blocks` drives.
pub(crate) trait RunningSums {
    /// Sets the running sums to zero (not the primary hits: sample 0 sets those).
    fn zero(&mut self) -> Result<()>;
    /// Adds samples `[start, start + count)` to the running sums, in sample order.
    fn add(&mut self, start: u32, count: u32) -> Result<()>;
    /// The sums of the two whole blocks from `first` (a block boundary), each added from zero
    /// in sample order: what `zero`, `add` and `read` give block by block, which is this
    /// default. The running sums are the second block's after it. The CPU overrides it to
    /// render both blocks' samples in one sweep, sixteen to a pixel's group of lanes.
    fn add_two_blocks(&mut self, first: u32) -> Result<[Sums; 2]> {
        Ok([block_sums(self, first, BLOCK_SAMPLES)?, block_sums(self, first + BLOCK_SAMPLES, BLOCK_SAMPLES)?])
    }
    /// The running sums (a GPU reads them back).
    fn read(&mut self) -> Result<Sums>;
    /// The primary hits, set by sample 0.
    fn primary(&mut self) -> Result<Vec<u32>>;
    /// The device's name for reports.
    fn name(&self) -> String;
}

/// The sums of samples `[first, first + count)` (one block) added from zero on `dev`: a whole
/// block at a time, as `multi`'s workers render them.
pub(crate) fn block_sums<D: RunningSums + ?Sized>(dev: &mut D, first: u32, count: u32) -> Result<Sums> {
    debug_assert!(first.is_multiple_of(BLOCK_SAMPLES) && count <= BLOCK_SAMPLES);
    dev.zero()?;
    dev.add(first, count)?;
    dev.read()
}

/// The block bookkeeping of a progressive render: where it started, the samples added and the
/// fold of the completed blocks.
pub(crate) struct Blocks {
    fold: Fold,
    first: u32,
    spp: u32,
}

impl Blocks {
    pub fn new(pixels: usize) -> Self {
        Self { fold: Fold::new(pixels), first: 0, spp: 0 }
    }

    /// The samples added so far (the end of the samples held).
    pub fn spp(&self) -> u32 {
        self.spp
    }

    /// `Progressive::start_at`.
    pub fn start_at(&mut self, start: u32) -> Result<()> {
        if self.spp != self.first {
            bail!("a render can be moved to another start only before its first pass");
        }
        if !start.is_multiple_of(BLOCK_SAMPLES) || start > MAX_SPP {
            bail!("a partial render starts on a block of {BLOCK_SAMPLES} samples, not at sample {start}");
        }
        (self.first, self.spp) = (start, start);
        Ok(())
    }

    /// `Progressive::pass`: cut at block boundaries; each block's sums start from zero and go
    /// into the fold when its last sample is added.
    pub fn pass(&mut self, dev: &mut dyn RunningSums, start: u32, count: u32) -> Result<()> {
        check_pass(self.spp, start, count)?;
        let end = start + count;
        let mut at = start;
        while at < end {
            if at.is_multiple_of(BLOCK_SAMPLES) && end - at >= 2 * BLOCK_SAMPLES {
                let k = block_of(at);
                for (j, sums) in dev.add_two_blocks(at)?.into_iter().enumerate() {
                    self.fold.insert(Node { id: NodeId::block(k + j as u32, BLOCK_SAMPLES), sums })?;
                }
                at += 2 * BLOCK_SAMPLES;
                self.spp = at;
                continue;
            }
            let block_end = (block_of(at) + 1) * BLOCK_SAMPLES;
            let n = end.min(block_end) - at;
            if at.is_multiple_of(BLOCK_SAMPLES) {
                dev.zero()?;
            }
            dev.add(at, n)?;
            at += n;
            self.spp = at;
            if at == block_end {
                let k = block_of(at - 1);
                self.fold.insert(Node { id: NodeId::block(k, BLOCK_SAMPLES), sums: dev.read()? })?;
            }
        }
        Ok(())
    }

    /// The running block (samples added to a block not yet complete), read from `dev`.
    fn running(&self, dev: &mut dyn RunningSums) -> Result<Option<Node>> {
        let within = self.spp % BLOCK_SAMPLES;
        if within == 0 {
            return Ok(None);
        }
        Ok(Some(Node { id: NodeId::block(block_of(self.spp), within), sums: dev.read()? }))
    }

    /// The image's sums so far (zero before any sample): `Progressive::image`.
    pub fn total(&self, dev: &mut dyn RunningSums) -> Result<Sums> {
        if self.first != 0 {
            bail!("a partial render from sample {} has no image of its own: merge it", self.first);
        }
        let running = self.running(dev)?;
        Ok(self.fold.total(running.as_ref())?.map_or_else(|| Sums::zero(self.fold.pixels()), |(s, _)| s))
    }

    /// `Progressive::nodes`.
    pub fn nodes(&self, dev: &mut dyn RunningSums) -> Result<Vec<Node>> {
        let mut fold = self.fold.clone();
        if let Some(r) = self.running(dev)? {
            fold.insert(r)?;
        }
        Ok(fold.into_nodes())
    }
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
