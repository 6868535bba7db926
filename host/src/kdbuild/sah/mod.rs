//! SAH k-d tree construction in O(N log N): Wald & Havran, "On building fast kd-Trees for Ray
//! Tracing, and on doing that in O(N log N)", IEEE Symposium on Interactive Ray Tracing 2006.
//!
//! - Events (start, end, or planar for a box flat on that axis) are sorted once per axis (a radix
//!   sort on position and kind, `event_sort`); every split partitions the sorted lists in O(N)
//!   without re-sorting (§5.3). Only the events of triangles that straddle the plane are made
//!   anew, from their clipped boxes (perfect splits, §4.3), and sorted and merged in: O(N log N)
//!   in all.
//! - One sweep per axis finds the plane of least cost over every candidate (§5.1); triangles lying
//!   in the plane go to the side that makes the split cheaper (§4.2). Most candidates are
//!   priced first by an estimate that multiplies where the cost divides; only those the
//!   estimate cannot rule out get the exact cost, which alone decides (`Sah::estimate`). The
//!   sweep takes sixteen events at a time, and a group whose least possible estimate lies
//!   above the best so far is passed over whole (on scanned meshes most runs are never
//!   priced).
//! - An event is one integer (position bits, kind, reference; `Event`) whose order is the sweep
//!   order, so sorting, merging and classifying events compare integers.
//! - Cost C = λ·(K_T + K_I·(P_L·T(N_L) + P_R·T(N_R))), where T(N) = ⌈N / leaf_block⌉ counts the
//!   leaf tests (8 triangles each by default, the SIMD leaf test; 1 gives the paper's N), with
//!   λ = `empty_factor` (0.8) when one side is empty and the plane is not flat on the voxel's
//!   boundary, else 1 (the project's seed).
//! - A node becomes a leaf when no split is cheaper than K_I·T(N), with pbrt-v3's allowance for a
//!   few splits that cost more ("bad refines", §4.4.2), at the depth limit, or when the split
//!   would exceed the node's share of the reference budget (`max_refs_factor`·N for the whole
//!   tree): long thin triangles crossing many cells (needles, fans) otherwise multiply their
//!   references until the depth limit, hundreds of times over.
//! - The two children of a large node are built in parallel (rayon); each subtree is laid out
//!   on its own and written into the final arrays once at the end, so the tree does not depend
//!   on the number of threads.
//! - The work is passes over events (the sweeps read more than the partitions write, and many
//!   sweeps end in a split that cuts off empty space; BENCHMARKS.md, "k-d build", has the
//!   counts). So the per-event work is kept
//!   branch-free and the bookkeeping off that path: lists come from pools that the build's
//!   tasks pass on to each other (`Stash`), so memory freed anywhere serves later nodes, a
//!   split with one empty side hands its lists to the other child unchanged, and a child that
//!   will be a leaf gets no events.
//!
//! One topic a file: `event` (the events and their sort), `run_masks` (the sweep's groups of
//! events as bit masks), `sweep` (the plane search and its screening), `partition` (the split),
//! `stash` (the buffer pools) and `subtree` (the layout of the parallel build); this file holds
//! the settings, the nodes and the recursion that ties them together.
mod event;
mod partition;
mod run_masks;
mod stash;
mod subtree;
mod sweep;

use super::clip::{clipped_box, to_f64, Aabb};
use super::{BuildSettings, KdTree, LeafTests};
use event::{push_events, sort_events, Event};
use rayon::prelude::*;
use shared::layout::{KdNode, Triangle};
use stash::{Scratch, Stash};
use subtree::{Part, Subtree};
use sweep::Plane;

/// Nodes with fewer references than this build their subtree on one thread.
const PARALLEL_MIN: usize = 4096;

/// A node under construction: its references (global triangle ids), events and voxel.
struct Node {
    triangles: Vec<u32>,
    events: [Vec<Event>; 3],
    voxel: Aabb,
    depth: u32,
    bad_refines: u32,
    /// References this subtree's leaves may hold in all (see `BuildSettings::max_refs_factor`).
    budget: f64,
}

/// The build's settings and the scene: what every task reads and none writes.
struct Sah<'a> {
    /// The scene's triangles, widened to f64 where they are clipped (exactly: every f32 is an
    /// f64), so the build keeps no second, f64 copy of the scene.
    triangles: &'a [Triangle],
    traversal_cost: f64,
    intersection_cost: f64,
    /// ⌈N / leaf block⌉ (`BuildSettings::leaf_block`).
    leaf_block: LeafTests,
    empty_factor: f64,
    max_depth: u32,
    leaf_size: usize,
    bad_refines: u32,
}

/// Builds the tree of `triangles` inside `bounds`, which holds them all, with `settings` and
/// the depth limit `max_depth`.
pub fn build(triangles: &[Triangle], bounds: Aabb, settings: &BuildSettings, max_depth: u32) -> KdTree {
    let sah = Sah {
        triangles,
        traversal_cost: settings.traversal_cost as f64,
        intersection_cost: settings.intersection_cost as f64,
        leaf_block: LeafTests::new(settings.leaf_block.max(1) as usize),
        empty_factor: settings.empty_factor as f64,
        max_depth,
        leaf_size: settings.leaf_size as usize,
        bad_refines: settings.bad_refines,
    };
    let stash = Stash::default();
    let boxes: Vec<Option<Aabb>> = triangles.par_iter().map(|t| clipped_box(&to_f64(t), &bounds)).collect();
    let budget = if settings.max_refs_factor > 0.0 {
        settings.max_refs_factor as f64 * triangles.len().max(1) as f64
    } else {
        f64::INFINITY
    };
    // The root's lists at their exact sizes: grown by doubling, each would be copied into fresh
    // memory a score of times, and this VM zeroes fresh pages slowly.
    let mut sizes = [0usize; 3];
    for b in boxes.iter().flatten() {
        for (k, size) in sizes.iter_mut().enumerate() {
            *size += if b.lo[k] == b.hi[k] { 1 } else { 2 };
        }
    }
    let events = sizes.map(Vec::with_capacity);
    let mut root = Node {
        triangles: Vec::with_capacity(triangles.len()),
        events,
        voxel: bounds,
        depth: 0,
        bad_refines: 0,
        budget,
    };
    for (id, b) in boxes.iter().enumerate() {
        if let Some(b) = b {
            push_events(&mut root.events, root.triangles.len(), b);
            root.triangles.push(id as u32);
        }
    }
    root.events.par_iter_mut().for_each(|list| {
        let mut scratch = stash.take();
        sort_events(list, &mut scratch.sort);
        // The sort's second buffer is the size of a root list: kept for the children's lists.
        let tmp = std::mem::take(&mut scratch.sort);
        scratch.recycle_events(tmp);
        stash.keep(scratch);
    });
    let part = sah.build_parallel(root, &stash);
    // The buffers are freed before the final arrays are made, so that those can take their
    // memory instead of fresh pages.
    drop(stash);
    let (nodes, indices) = part.size();
    let mut out = Subtree { nodes: Vec::with_capacity(nodes), indices: Vec::with_capacity(indices), depth: 0 };
    part.write(&mut out);
    KdTree {
        nodes: out.nodes,
        indices: out.indices,
        bounds_min: shared::glam::Vec3::from(bounds.lo),
        bounds_max: shared::glam::Vec3::from(bounds.hi),
        depth: out.depth,
    }
}

impl Sah<'_> {
    /// Leaf tests for `n` triangles (`super::leaf_tests`), as an f64: through i64, which x86-64
    /// converts in one instruction, where an unsigned conversion takes ten without AVX-512 (the
    /// same value: counts are far below 2^53).
    #[inline]
    fn leaf_tests(&self, n: usize) -> f64 {
        self.leaf_block.count(n) as i64 as f64
    }

    /// Builds `node`'s subtree, the two children of a node of at least `PARALLEL_MIN`
    /// references in parallel, each laid out on its own (`Part`).
    fn build_parallel(&self, node: Node, stash: &Stash) -> Part {
        let mut scratch = stash.take();
        if node.triangles.len() < PARALLEL_MIN {
            let mut out = Subtree::default();
            self.build_into(node, &mut out, &mut scratch);
            stash.keep(scratch);
            return Part::Built(out);
        }
        match self.decide(&node) {
            None => {
                stash.keep(scratch);
                let mut out = Subtree::default();
                let mut node = node;
                out.leaf(&mut node.triangles, node.depth);
                Part::Built(out)
            }
            Some((plane, bad)) => {
                let (below, above) = self.split(node, plane, bad, &mut scratch);
                stash.keep(scratch);
                let (b, a) = rayon::join(|| self.build_parallel(below, stash), || self.build_parallel(above, stash));
                Part::Split { axis: plane.axis as u32, pos: plane.pos, children: Box::new((b, a)) }
            }
        }
    }

    /// Builds `node`'s subtree on this thread, depth first into `out`.
    fn build_into(&self, node: Node, out: &mut Subtree, scratch: &mut Scratch) {
        match self.decide(&node) {
            None => {
                let mut node = node;
                out.leaf(&mut node.triangles, node.depth);
                scratch.recycle(node);
            }
            Some((plane, bad)) => {
                let (below, above) = self.split(node, plane, bad, scratch);
                let me = out.nodes.len();
                out.nodes.push(KdNode::default());
                self.build_into(below, out, scratch);
                out.nodes[me] = KdNode::interior(plane.axis as u32, plane.pos, out.nodes.len() as u32);
                self.build_into(above, out, scratch);
            }
        }
    }

    /// The plane to split at and the bad refines spent so far, or `None` for a leaf.
    fn decide(&self, node: &Node) -> Option<(Plane, u32)> {
        let n = node.triangles.len();
        if n <= self.leaf_size || node.depth >= self.max_depth {
            return None;
        }
        let plane = self.find_plane(node)?;
        if (plane.below + plane.above) as f64 > node.budget {
            return None;
        }
        let leaf_cost = self.intersection_cost * self.leaf_tests(n);
        if plane.cost < leaf_cost {
            return Some((plane, node.bad_refines));
        }
        // pbrt-v3: a few costlier splits may lead to cheap ones further down, but not for
        // small nodes where the split is far worse than the leaf.
        let bad = node.bad_refines + 1;
        if bad > self.bad_refines || (plane.cost > 4.0 * leaf_cost && n < 16) {
            return None;
        }
        Some((plane, bad))
    }
}
