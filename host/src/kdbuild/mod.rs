//! k-d tree construction on the host. The node layout (`shared::layout::KdNode`: 8 bytes, the
//! below child adjacent, leaves as runs of one index list) and the traversal
//! (`shared::kdtree`) are shared with the GPU kernel; only building happens here.
//!
//! - `sah`: Wald & Havran's O(N log N) SAH build with perfect splits (the default);
//!   `event_sort` sorts its events.
//! - `median`: spatial-median splits, a baseline for benchmarks.
//! - `validate`: checks every invariant the traversal relies on.
//! - `stats`: node and reference counts and the tree's SAH cost.
mod clip;
mod event_sort;
mod median;
mod sah;
mod stats;
mod validate;

pub use clip::Aabb;
pub use stats::{stats, TreeStats};
pub use validate::{check_structure, validate};

use serde::{Deserialize, Serialize};
use shared::glam::Vec3;
use shared::layout::{KdNode, Triangle, BLOCK_WIDTH, KD_MAX_DEPTH};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Builder {
    /// Surface area heuristic, Wald & Havran 2006 (the default).
    Sah,
    /// Spatial median of the longest axis.
    Median,
}

/// How to build the tree. The defaults are for the CPU's eight-lane leaf test (`for_gpu` for a
/// GPU's one-by-one test), with Wald & Havran's K_T and the seed's λ.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BuildSettings {
    pub builder: Builder,
    /// K_T, the cost of one traversal step (default 15).
    pub traversal_cost: f32,
    /// K_I, the cost of one leaf test of up to `leaf_block` triangles (default 4: an eight-lane
    /// test measured about a quarter of a node step on the CPU; `for_gpu`: 20 per triangle,
    /// Wald & Havran's).
    pub intersection_cost: f32,
    /// Triangles one leaf test covers in the SAH (default 8, `shared::layout::BLOCK_WIDTH`: the
    /// CPU tests a leaf's triangles eight at a time in SIMD lanes, so a leaf of 1 to 8 costs one
    /// test). 1 counts every triangle, Wald & Havran's model and how a GPU thread tests them.
    pub leaf_block: u32,
    /// λ, the factor on the cost of a split with one empty side whose plane is not on the
    /// voxel's boundary (default 0.8: favour cutting off empty space).
    pub empty_factor: f32,
    /// Maximum depth; 0 picks 8 + 1.3·log2(N) (pbrt-v3). Never beyond `KD_MAX_DEPTH`, the depth
    /// the full traversal stack holds.
    pub max_depth: u32,
    /// Nodes with at most this many triangles become leaves without trying a split (default 1:
    /// the SAH decides; the median builder uses at least 4).
    pub leaf_size: u32,
    /// Splits costlier than a leaf allowed on one path from the root (default 2, pbrt-v3's).
    pub bad_refines: u32,
    /// SAH builder: leaves may hold at most this many triangle references per triangle in all
    /// (default 16; 0 lifts the limit). A safety cap, not a heuristic: real meshes stay well
    /// below it (the bunny's tree holds 7.8 per triangle).
    pub max_refs_factor: f32,
}

impl Default for BuildSettings {
    fn default() -> Self {
        Self {
            builder: Builder::Sah,
            traversal_cost: 15.0,
            intersection_cost: 4.0,
            leaf_block: BLOCK_WIDTH,
            empty_factor: 0.8,
            max_depth: 0,
            leaf_size: 1,
            bad_refines: 2,
            max_refs_factor: 16.0,
        }
    }
}

impl BuildSettings {
    /// The defaults for a tree a GPU traverses. Its threads test a leaf's triangles one by one
    /// (`shared::kdtree::test_leaf`), so a leaf costs K_I per triangle: Wald & Havran's model
    /// and costs (K_T = 15, K_I = 20), which lavapipe also ran fastest (BENCHMARKS.md).
    pub fn for_gpu() -> Self {
        Self { intersection_cost: 20.0, leaf_block: 1, ..Self::default() }
    }

    /// Rejects settings that would make the SAH meaningless or the tree unusable.
    pub fn check(&self) -> anyhow::Result<()> {
        let finite_positive = |x: f32| x.is_finite() && x > 0.0;
        if !finite_positive(self.traversal_cost) || !finite_positive(self.intersection_cost) {
            anyhow::bail!(
                "traversal and intersection costs must be finite and positive (got {} and {})",
                self.traversal_cost,
                self.intersection_cost
            );
        }
        if !(1..=64).contains(&self.leaf_block) {
            anyhow::bail!("leaf block {} must be 1 to 64 triangles", self.leaf_block);
        }
        if !(self.empty_factor > 0.0 && self.empty_factor <= 1.0) {
            anyhow::bail!("empty-space factor {} must be in (0, 1]", self.empty_factor);
        }
        if !(self.max_refs_factor == 0.0 || (self.max_refs_factor.is_finite() && self.max_refs_factor >= 1.0)) {
            anyhow::bail!("reference budget factor {} must be 0 (no limit) or at least 1", self.max_refs_factor);
        }
        if self.max_depth > KD_MAX_DEPTH {
            anyhow::bail!(
                "max depth {} exceeds {KD_MAX_DEPTH}, the deepest tree the traversal stack holds",
                self.max_depth
            );
        }
        Ok(())
    }

    /// The leaf tests `n` triangles take: ⌈n / leaf_block⌉.
    pub fn leaf_tests(&self, n: usize) -> usize {
        leaf_tests(n, self.leaf_block.max(1) as usize)
    }

    /// The depth limit for `n` triangles.
    pub fn depth_limit(&self, n: usize) -> u32 {
        if self.max_depth == 0 {
            default_max_depth(n)
        } else {
            self.max_depth.min(KD_MAX_DEPTH)
        }
    }
}

#[derive(Clone, Debug, Default)]
pub struct KdTree {
    pub nodes: Vec<KdNode>,
    pub indices: Vec<u32>,
    pub bounds_min: Vec3,
    pub bounds_max: Vec3,
    pub depth: u32,
}

/// ⌈n / block⌉, the leaf tests of `n` triangles in blocks of `block` (at least 1).
#[inline]
pub fn leaf_tests(n: usize, block: usize) -> usize {
    LeafTests::new(block).count(n)
}

/// ⌈n / block⌉ for one block width, as an add, a multiply and a shift: a division by a width
/// known only at run time is tens of cycles, and the SAH sweep asks twice per candidate plane.
/// The multiplier is Granlund & Montgomery's (1994) ⌈2^(32+l) / block⌉ with l = ⌈log2 block⌉,
/// exact for every dividend below 2^32 (`n + block - 1`, references being fewer than 2^30);
/// for a power of two it is a plain shift.
#[derive(Clone, Copy, Debug)]
pub struct LeafTests {
    round: u64,
    magic: u64,
    shift: u32,
}

impl LeafTests {
    pub fn new(block: usize) -> Self {
        let block = block.max(1) as u64;
        let l = block.next_power_of_two().trailing_zeros();
        Self { round: block - 1, magic: (1u64 << (32 + l)).div_ceil(block), shift: 32 + l }
    }

    #[inline]
    pub fn count(self, n: usize) -> usize {
        debug_assert!((n as u64 + self.round) < 1 << 32);
        (((n as u64 + self.round) * self.magic) >> self.shift) as usize
    }
}

/// Marsaglia's xorshift64: a seeded stream of inputs for the builder's randomised tests.
#[cfg(test)]
fn xorshift(mut state: u64) -> impl FnMut() -> u64 {
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    }
}

/// The automatic depth limit (pbrt-v3's 8 + 1.3·log2 N), never beyond the traversal stack.
pub fn default_max_depth(n: usize) -> u32 {
    let d = (8.0 + 1.3 * (n.max(1) as f64).log2()).round() as u32;
    d.min(KD_MAX_DEPTH)
}

/// Builds the tree of `triangles` inside the box [bounds_min, bounds_max], which must contain
/// them all.
pub fn build(triangles: &[Triangle], bounds_min: Vec3, bounds_max: Vec3, settings: BuildSettings) -> KdTree {
    let max_depth = settings.depth_limit(triangles.len());
    let mut tree = match settings.builder {
        Builder::Median => median::build(triangles, bounds_min, bounds_max, settings.leaf_size.max(4), max_depth),
        Builder::Sah => {
            sah::build(triangles, Aabb { lo: bounds_min.to_array(), hi: bounds_max.to_array() }, &settings, max_depth)
        }
    };
    align_leaves(&mut tree);
    tree
}

/// Lays the index list out for the CPU's leaf test (`shared::kdtree::test_leaf_blocks`), which
/// tests whole blocks of `BLOCK_WIDTH` entries without masking lanes: every non-empty leaf's run starts
/// at a multiple of `BLOCK_WIDTH`, and the entries after a run up to the next multiple repeat the
/// run's last triangle (the list's length is a multiple too). A repeated triangle hits at the
/// same distance as its first copy, which comes first and wins the tie, so the extra lanes never
/// change a hit. Does nothing to a tree already laid out so (every builder's output).
pub fn align_leaves(tree: &mut KdTree) {
    if is_aligned(tree) {
        return;
    }
    let width = BLOCK_WIDTH as usize;
    let mut out = Vec::with_capacity(tree.indices.len() + tree.indices.len() / 2);
    let pad = |out: &mut Vec<u32>| {
        while !out.len().is_multiple_of(width) {
            out.push(*out.last().expect("a length that is not a multiple of the width is not zero"));
        }
    };
    for n in tree.nodes.iter_mut().filter(|n| n.is_leaf()) {
        let (first, count) = (n.first_index() as usize, n.count() as usize);
        if count > 0 {
            pad(&mut out);
        }
        *n = KdNode::leaf(out.len() as u32, count as u32);
        out.extend_from_slice(&tree.indices[first..first + count]);
    }
    pad(&mut out);
    tree.indices = out;
}

/// Whether `tree` is laid out as `align_leaves` lays it out.
pub fn is_aligned(tree: &KdTree) -> bool {
    let width = BLOCK_WIDTH as usize;
    tree.indices.len().is_multiple_of(width)
        && tree.nodes.iter().filter(|n| n.is_leaf() && n.count() > 0).all(|n| {
            let (first, end) = (n.first_index() as usize, (n.first_index() + n.count()) as usize);
            let padded = end.div_ceil(width) * width;
            first % width == 0
                && tree.indices.get(end - 1..padded).is_some_and(|tail| tail.iter().all(|&id| id == tail[0]))
        })
}

#[cfg(test)]
mod leaf_tests_tests {
    use super::LeafTests;

    /// The multiply and shift give ⌈n / block⌉ for every width the settings allow, at small
    /// counts, around multiples of the width and up to the largest count a build can ask.
    #[test]
    fn leaf_tests_divide_exactly() {
        for block in 1..=64usize {
            let tests = LeafTests::new(block);
            let mut counts: Vec<usize> = (0..5000).collect();
            for m in [1usize << 10, 1 << 20, (1 << 30) / block] {
                counts.extend((m * block).saturating_sub(3)..m * block + 3);
            }
            counts.push((1 << 30) - 1);
            for n in counts {
                assert_eq!(tests.count(n), n.div_ceil(block), "{n} triangles in blocks of {block}");
            }
        }
    }
}
