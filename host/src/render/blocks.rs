//! Fixed sample blocks and the fixed dyadic fold of their sums: what makes any split of a
//! render's samples (passes, partial renders merged later, several devices at once) add up to
//! the same image bit for bit.
//!
//! f32 sums are not associative, so a pixel's sum must be added in one order whatever the
//! split. The samples are cut into blocks of `BLOCK_SAMPLES`: block `k` holds samples
//! `[8k, min(8k + 8, N))` and its sums are added sequentially from zero on one device (the
//! integrator's own loop, the device's buffer zeroed at the block's start). Blocks are then
//! added along a fixed binary tree over their absolute indices: a node covering blocks
//! `[a, a + 2^j)`, `a` a multiple of `2^j`, holds left + right (f32 per component, sums and
//! sums of squares; sample counts as integers). A node's value depends on its interval alone,
//! whoever computed its blocks and in whatever order they arrived. The image over blocks
//! `[0, n)` is the fold of the canonical decomposition of `[0, n)` (the maximal aligned nodes,
//! the binary representation of `n`), added left to right: `((n₀ + n₁) + n₂) + …`.
//!
//! `Fold` keeps the nodes present and merges two siblings as soon as both are there (a binary
//! counter when blocks come in order; blocks out of order wait for their siblings), so what it
//! holds is always the maximal aligned nodes of the blocks it was given.
use anyhow::{bail, Result};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use shared::glam::Vec4;

/// Samples per block. A constant of the image's definition: changing it changes every image's
/// bits (not their statistics), and partial files of different block sizes do not merge (the
/// file format's version names it).
pub const BLOCK_SAMPLES: u32 = 8;

/// The block that holds sample `sample`.
pub fn block_of(sample: u32) -> u32 {
    sample / BLOCK_SAMPLES
}

/// Per-pixel sums of radiance (`xyz`, zeroed samples in `w`) and of its squares.
#[derive(Clone, Debug, PartialEq)]
pub struct Sums {
    pub sum: Vec<Vec4>,
    pub sum_sq: Vec<Vec4>,
}

impl Sums {
    pub fn zero(pixels: usize) -> Self {
        Self { sum: vec![Vec4::ZERO; pixels], sum_sq: vec![Vec4::ZERO; pixels] }
    }

    /// `self + right`, per pixel and component: the fold's one operation (each pixel on its own,
    /// so rayon's split changes no bit; a large image's fold costs a fraction of a block).
    fn add(&self, right: &Sums) -> Sums {
        let add = |a: &[Vec4], b: &[Vec4]| a.par_iter().zip(b).map(|(a, b)| *a + *b).collect();
        Sums { sum: add(&self.sum, &right.sum), sum_sq: add(&self.sum_sq, &right.sum_sq) }
    }

    fn add_assign(&mut self, right: &Sums) {
        let add = |a: &mut [Vec4], b: &[Vec4]| a.par_iter_mut().zip(b).for_each(|(a, b)| *a += *b);
        add(&mut self.sum, &right.sum);
        add(&mut self.sum_sq, &right.sum_sq);
    }
}

/// Where a node sits in the fold's tree: blocks `[index·2^level, (index + 1)·2^level)` (the
/// render's last block may be short), holding samples `[first, first + samples)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct NodeId {
    pub level: u32,
    pub index: u32,
    pub first: u32,
    pub samples: u32,
}

impl NodeId {
    /// Block `k` holding `samples` samples (`BLOCK_SAMPLES`, fewer for a render's last block).
    pub fn block(k: u32, samples: u32) -> Self {
        Self { level: 0, index: k, first: k * BLOCK_SAMPLES, samples }
    }

    /// The first block it covers.
    pub fn first_block(&self) -> u64 {
        (self.index as u64) << self.level
    }

    /// One past the last block it covers.
    pub fn end_block(&self) -> u64 {
        (self.index as u64 + 1) << self.level
    }

    /// One past its last sample.
    pub fn end(&self) -> u32 {
        self.first + self.samples
    }

    /// Whether the fields agree: aligned blocks, samples within them, only a last block short.
    pub fn check(&self) -> Result<()> {
        // Wide enough for any u32 fields: a crafted file's node is an error, not an overflow.
        let (b, f, n) = (BLOCK_SAMPLES as u128, self.first as u128, self.samples as u128);
        if self.level >= 32 {
            bail!("node {self:?} is not a node of the fold of {BLOCK_SAMPLES}-sample blocks");
        }
        let full = (1u128 << self.level) * b;
        if f != self.first_block() as u128 * b || n == 0 || n > full || n <= full - b || f + n > u32::MAX as u128 {
            bail!("node {self:?} is not a node of the fold of {BLOCK_SAMPLES}-sample blocks");
        }
        Ok(())
    }
}

/// A node and its sums.
#[derive(Clone, Debug)]
pub struct Node {
    pub id: NodeId,
    pub sums: Sums,
}

/// The fold's nodes: the maximal aligned nodes of the blocks inserted so far, in block order.
#[derive(Clone, Debug)]
pub struct Fold {
    pixels: usize,
    nodes: Vec<Node>,
}

impl Fold {
    pub fn new(pixels: usize) -> Self {
        Self { pixels, nodes: Vec::new() }
    }

    pub fn pixels(&self) -> usize {
        self.pixels
    }

    /// The nodes held, in block order.
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    pub fn into_nodes(self) -> Vec<Node> {
        self.nodes
    }

    /// Adds a node (a block, or a node read from a partial file): merged with its sibling if
    /// that is here, and the result with its own sibling, and so on. An error if it overlaps a
    /// node held, if its sibling's samples do not meet it (a short block followed by more), or
    /// if its sums are not the image's size.
    pub fn insert(&mut self, node: Node) -> Result<()> {
        node.id.check()?;
        if node.sums.sum.len() != self.pixels || node.sums.sum_sq.len() != self.pixels {
            bail!("node {:?} holds {} pixels, the image {}", node.id, node.sums.sum.len(), self.pixels);
        }
        let mut node = node;
        loop {
            let (lo, hi) = (node.id.first_block(), node.id.end_block());
            if let Some(o) = self.nodes.iter().find(|n| n.id.first_block() < hi && lo < n.id.end_block()) {
                bail!(
                    "samples {}..{} are there twice (in {}..{})",
                    node.id.first,
                    node.id.end(),
                    o.id.first,
                    o.id.end()
                );
            }
            let sibling = NodeId { index: node.id.index ^ 1, ..node.id };
            let Some(at) = self.nodes.iter().position(|n| n.id.level == sibling.level && n.id.index == sibling.index)
            else {
                let at = self.nodes.partition_point(|n| n.id.first_block() < lo);
                self.nodes.insert(at, node);
                return Ok(());
            };
            let other = self.nodes.remove(at);
            let (left, right) = if node.id.index & 1 == 0 { (node, other) } else { (other, node) };
            if left.id.end() != right.id.first {
                bail!(
                    "samples {}..{} end short of block {}, whose samples {}..{} follow: only a render's last block is short",
                    left.id.first,
                    left.id.end(),
                    right.id.first_block(),
                    right.id.first,
                    right.id.end()
                );
            }
            node = Node {
                id: NodeId {
                    level: left.id.level + 1,
                    index: left.id.index >> 1,
                    first: left.id.first,
                    samples: left.id.samples + right.id.samples,
                },
                sums: left.sums.add(&right.sums),
            };
        }
    }

    /// The samples the nodes cover, if they follow each other from sample 0 with no gap:
    /// `Some(n)` for samples `[0, n)`.
    pub fn prefix(&self) -> Option<u32> {
        let mut end = 0;
        for n in &self.nodes {
            if n.id.first != end {
                return None;
            }
            end = n.id.end();
        }
        Some(end)
    }

    /// The image's sums over samples `[0, n)`, the nodes held (then the canonical decomposition
    /// of their blocks) added left to right, with `running` (the next block, still being added
    /// to) inserted first as if complete, so that a finished render's image is the fold of its
    /// blocks, nothing else. `None` without any sample; an error unless the nodes cover
    /// `[0, n)` with no gap and `running` follows them.
    pub fn total(&self, running: Option<&Node>) -> Result<Option<(Sums, u32)>> {
        let Some(running) = running else { return self.fold_left(&self.nodes) };
        // The running block's carries: each sibling it meets is one of the last nodes held.
        let mut kept = self.nodes.len();
        let mut carried: Option<Node> = None;
        let mut id = running.id;
        while kept > 0 {
            let last = &self.nodes[kept - 1].id;
            if !(last.level == id.level && last.index == (id.index ^ 1) && id.index & 1 == 1) {
                break;
            }
            let right = carried.as_ref().map_or(&running.sums, |c| &c.sums);
            let sums = self.nodes[kept - 1].sums.add(right);
            id = NodeId {
                level: id.level + 1,
                index: id.index >> 1,
                first: last.first,
                samples: last.samples + id.samples,
            };
            carried = Some(Node { id, sums });
            kept -= 1;
        }
        let last = carried.as_ref().unwrap_or(running);
        let mut nodes: Vec<&Node> = self.nodes[..kept].iter().collect();
        nodes.push(last);
        self.fold_left(nodes)
    }

    fn fold_left<'a>(&self, nodes: impl IntoIterator<Item = &'a Node>) -> Result<Option<(Sums, u32)>> {
        let mut acc: Option<(Sums, u32)> = None;
        let mut end = 0u32;
        for n in nodes {
            if n.id.first != end {
                bail!("the fold needs samples {end}..{} before samples {}..{}", n.id.first, n.id.first, n.id.end());
            }
            end = n.id.end();
            match &mut acc {
                None => acc = Some((n.sums.clone(), n.id.samples)),
                Some((s, count)) => {
                    s.add_assign(&n.sums);
                    *count += n.id.samples;
                }
            }
        }
        Ok(acc)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One pixel whose sample `i` is `value(i)`: sums of a block from zero, as a device adds them.
    fn block(k: u32, n: u32, value: impl Fn(u32) -> f32) -> Node {
        let first = k * BLOCK_SAMPLES;
        let samples = BLOCK_SAMPLES.min(n - first);
        let mut s = Sums::zero(1);
        for i in first..first + samples {
            let v = value(i);
            s.sum[0] += Vec4::new(v, v, v, 0.0);
            s.sum_sq[0] += Vec4::new(v * v, v * v, v * v, 0.0);
        }
        Node { id: NodeId::block(k, samples), sums: s }
    }

    fn value(i: u32) -> f32 {
        // Values of many magnitudes, so that the order of addition shows in the bits.
        ((i * 2654435761u32) >> 8) as f32 * 1e-3 + 1.0 / (i + 1) as f32
    }

    fn bits(s: &Sums) -> Vec<u32> {
        s.sum.iter().chain(&s.sum_sq).flat_map(|v| v.to_array().map(f32::to_bits)).collect()
    }

    #[test]
    fn any_order_of_blocks_gives_the_same_bits() {
        for n in [1u32, 7, 8, 9, 24, 28, 64, 100, 131] {
            let blocks = n.div_ceil(BLOCK_SAMPLES);
            let mut in_order = Fold::new(1);
            for k in 0..blocks {
                in_order.insert(block(k, n, value)).unwrap();
            }
            let (want, count) = in_order.total(None).unwrap().unwrap();
            assert_eq!(count, n);
            // Reversed, and interleaved from both ends.
            let mut reversed = Fold::new(1);
            for k in (0..blocks).rev() {
                reversed.insert(block(k, n, value)).unwrap();
            }
            assert_eq!(bits(&reversed.total(None).unwrap().unwrap().0), bits(&want), "n = {n}");
            // The running block inserted virtually: the same as inserted.
            if blocks > 1 {
                let mut before = Fold::new(1);
                for k in 0..blocks - 1 {
                    before.insert(block(k, n, value)).unwrap();
                }
                let running = block(blocks - 1, n, value);
                assert_eq!(bits(&before.total(Some(&running)).unwrap().unwrap().0), bits(&want), "n = {n}");
            }
        }
    }

    #[test]
    fn the_fold_differs_from_a_sequential_sum_yet_holds_the_same_samples() {
        let n = 64;
        let mut fold = Fold::new(1);
        for k in 0..n / BLOCK_SAMPLES {
            fold.insert(block(k, n, value)).unwrap();
        }
        assert_eq!(fold.nodes().len(), 1, "64 samples are one node of level 3");
        assert_eq!(fold.nodes()[0].id, NodeId { level: 3, index: 0, first: 0, samples: 64 });
        let (s, _) = fold.total(None).unwrap().unwrap();
        let sequential: f32 = (0..n).map(value).sum();
        assert!((s.sum[0].x - sequential).abs() <= 1e-4 * sequential);
    }

    #[test]
    fn overlaps_gaps_and_short_blocks_inside_are_refused() {
        let mut f = Fold::new(1);
        f.insert(block(0, 64, value)).unwrap();
        assert!(f.insert(block(0, 64, value)).is_err(), "twice");
        f.insert(block(2, 64, value)).unwrap();
        assert_eq!(f.prefix(), None);
        assert!(f.total(None).is_err(), "a gap");
        // A short block 1 cannot be followed by block 2's samples: found when the fold is taken,
        // or when the two meet in a node.
        f.insert(block(1, 12, value)).unwrap();
        assert!(f.total(None).is_err(), "samples 12..16 are missing");
        let mut g = Fold::new(1);
        for k in [2, 3, 0] {
            g.insert(block(k, 64, value)).unwrap();
        }
        assert!(g.insert(block(1, 12, value)).is_err());
        assert!(f
            .insert(Node { id: NodeId { level: 1, index: 0, first: 0, samples: 3 }, sums: Sums::zero(1) })
            .is_err());
        assert!(f.insert(Node { id: NodeId::block(5, 8), sums: Sums::zero(2) }).is_err(), "size");
        // Fields from a crafted file: errors, not overflows.
        for id in [
            NodeId { level: 40, index: 0, first: 0, samples: 8 },
            NodeId { level: 3, index: u32::MAX, first: 0, samples: 64 },
            NodeId { level: 0, index: u32::MAX / 8, first: u32::MAX / 8 * 8, samples: 8 },
            NodeId { level: 31, index: 1, first: 0, samples: u32::MAX },
        ] {
            assert!(id.check().is_err(), "{id:?}");
        }
    }
}
