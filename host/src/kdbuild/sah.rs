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
//!   above the best so far is passed over whole (on the bunny, two runs in three are never
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
//! - The work is passes over events: on the bunny's tree (eight-triangle leaves, about 37
//!   references a leaf) the sweeps read 8.8 M events and the partitions 5.5 M, about a fifth of
//!   the sweeps ending in a split that cuts off empty space. So the per-event work is kept
//!   branch-free and the bookkeeping off that path: lists come from pools that the build's
//!   tasks pass on to each other (`Stash`), so memory freed anywhere serves later nodes, a
//!   split with one empty side hands its lists to the other child unchanged, and a child that
//!   will be a leaf gets no events.
use super::clip::{clipped_box, clipped_box_with, split_boxes, to_f64, Aabb, ClipBuffers};
use super::{event_sort, BuildSettings, KdTree, LeafTests};
use rayon::prelude::*;
use shared::layout::{KdNode, Triangle};
use std::mem::MaybeUninit;
use std::simd::prelude::*;

const END: u32 = 0;
const PLANAR: u32 = 1;
const START: u32 = 2;

/// How many references ahead the partition fetches a straddler's vertices.
const PREFETCH_AHEAD: usize = 8;

/// Asks for the cache line holding `x`: a hint, with no effect on results.
#[inline(always)]
fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch reads nothing and cannot fault; the pointer comes from a reference.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>((x as *const T).cast::<i8>())
    };
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}

/// The partition's word per reference (`Sah::split`): the side that keeps its events
/// (`KEEP_BELOW`, `KEEP_ABOVE`, or neither for a straddler, whose events are made anew), then
/// also its index in that child, in the low bits, where a moved event wants it.
const STRADDLES: u32 = 0;
const KEEP_BELOW: u32 = 1 << 30;
const KEEP_ABOVE: u32 = 1 << 31;
const INDEX: u32 = (1 << 30) - 1;

/// Nodes with fewer references than this build their subtree on one thread.
const PARALLEL_MIN: usize = 4096;

/// Bits of an event that hold its node-local reference (scenes have fewer than 2^30 triangles).
const REFERENCE_BITS: u32 = 30;
const REFERENCE_MASK: u64 = (1 << REFERENCE_BITS) - 1;

/// One event, packed into one integer whose order is the sweep's: the position as
/// `event_sort::ordered_bits` (bits 32–63, an unsigned integer in the float's order), the kind
/// (bits 30–31: end < planar < start, Wald & Havran §5.1) and the node-local reference
/// (bits 0–29). Comparing, sorting and merging events are then integer operations, the radix
/// sort's key is a shift, and a position is decoded back to a float only where a plane's cost
/// is computed. Within a node the references are 0..N, so partition flags are a plain array
/// even when sibling subtrees are built in parallel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
#[repr(transparent)]
struct Event(u64);

impl Event {
    fn new(pos: f32, reference: usize, kind: u32) -> Self {
        // -0.0 + 0.0 = +0.0: both zeros sort and compare as one position.
        let bits = event_sort::ordered_bits(pos + 0.0) as u64;
        Self((bits << 32) | ((kind as u64) << REFERENCE_BITS) | reference as u64)
    }
    /// The position in `event_sort::ordered_bits` form: compares as the position does.
    #[inline]
    fn pos_bits(self) -> u32 {
        (self.0 >> 32) as u32
    }
    #[cfg(test)]
    fn pos(self) -> f32 {
        event_sort::position_of(self.pos_bits())
    }
    #[inline]
    fn reference(self) -> usize {
        (self.0 & REFERENCE_MASK) as usize
    }
    #[cfg(test)]
    fn kind(self) -> u32 {
        (self.0 >> REFERENCE_BITS) as u32 & 3
    }
    /// Position and kind: the sweep order.
    #[inline]
    fn key(self) -> u64 {
        self.0 >> REFERENCE_BITS
    }
}

/// Events a sweep takes at once (`run_masks`).
const LANES: usize = 16;

/// Where runs of events at one position end among the `LANES` events from `first`, and which of
/// them are ends and which planars, as bit masks (bit l for `events[first + l]`; past the
/// list's end, nothing). The events are compared with their successors at once
/// (`core::simd`), with no dependence on where the previous run ended: on a mesh a run is a
/// vertex shared by a few triangles, one to eight events of no predictable count, and a loop that
/// stopped at each run's end mispredicted that stop at nearly every run.
#[inline]
fn run_masks(raw: &[u64], first: usize) -> Group {
    type Lanes = Simd<u64, LANES>;
    const KIND: u64 = 3 << REFERENCE_BITS;
    let kinds = |v: Lanes| {
        let k = v & Lanes::splat(KIND);
        (
            k.simd_eq(Lanes::splat((END as u64) << REFERENCE_BITS)).to_bitmask() as u32,
            k.simd_eq(Lanes::splat((PLANAR as u64) << REFERENCE_BITS)).to_bitmask() as u32,
        )
    };
    let masks = |events: &[u64]| {
        let (v, w) = (Lanes::from_slice(&events[..LANES]), Lanes::from_slice(&events[1..LANES + 1]));
        let runs = (v >> 32).simd_ne(w >> 32).to_bitmask() as u32;
        let (ends, planar) = kinds(v);
        Group { runs, ends, planar, bits: (v >> 32).cast::<u32>().to_array() }
    };
    if raw.len() > first + LANES {
        return masks(&raw[first..]);
    }
    // The list's last few events, padded with events of no kind at a position no event has
    // (positions are never NaN): the last real event ends its run, and the masks are cut to
    // the real ones. Most lists of a deep tree are this short.
    let rest = raw.len() - first;
    let mut padded = [u64::MAX; LANES + 1];
    padded[..rest].copy_from_slice(&raw[first..]);
    let mut g = masks(&padded);
    let real = (1u32 << rest) - 1;
    (g.runs, g.ends, g.planar) = (g.runs & real, g.ends & real, g.planar & real);
    g
}

/// The sweep's bookkeeping redone one event at a time, for tests: the counts `Sah::sweep` keeps
/// at each group must be these, and every run in a group or block it passes over must have a
/// bound above the threshold, as the per-run screen would have found.
#[cfg(test)]
#[derive(Default)]
struct SweepCheck {
    next: usize,
    ends: usize,
    planars: usize,
    below: usize,
    planar_done: usize,
}

#[cfg(test)]
impl SweepCheck {
    /// Steps to event `to`, calling `run` with (bits, below, planar, above) at each run end.
    fn advance(&mut self, raw: &[u64], n: usize, to: usize, mut run: impl FnMut(u32, usize, usize, usize)) {
        while self.next < to.min(raw.len()) {
            let e = Event(raw[self.next]);
            self.ends += (e.kind() == END) as usize;
            self.planars += (e.kind() == PLANAR) as usize;
            if raw.get(self.next + 1).is_none_or(|&x| x >> 32 != raw[self.next] >> 32) {
                run(e.pos_bits(), self.below, self.planars - self.planar_done, n - self.ends - self.planars);
                self.below = self.next + 1 - self.ends;
                self.planar_done = self.planars;
            }
            self.next += 1;
        }
    }

    fn state(&mut self, raw: &[u64], first: usize, kept: (usize, usize, usize, usize)) {
        self.advance(raw, 0, first, |_, _, _, _| {});
        assert_eq!(
            kept,
            (self.ends, self.planars, self.below, self.planar_done),
            "the sweep's counts at event {first}"
        );
    }

    fn passed_over(&mut self, sah: &Sah, raw: &[u64], n: usize, sweep: &Sweep, to: usize, threshold: f64) {
        self.advance(raw, n, to, |bits, below, planar, above| {
            let bound =
                sah.screened(sah.estimate(sweep, bits, below, above), (planar != 0) | (below == 0) | (above == 0));
            assert!(bound > threshold, "a run passed over at {bits:#x} has bound {bound} not above {threshold}");
        });
    }
}

/// Events a sweep screens at once before it looks at their groups (`Sah::sweep`).
const BLOCK: usize = 4 * LANES;

/// The starts and the planars among `events`.
#[inline]
fn kind_counts(events: &[u64]) -> (usize, usize) {
    type Lanes = Simd<u64, 8>;
    let (mut starts, mut planars) = (Lanes::splat(0), Lanes::splat(0));
    for chunk in events.chunks_exact(8) {
        let kind = (Lanes::from_slice(chunk) >> REFERENCE_BITS as u64) & Lanes::splat(3);
        starts += kind >> 1;
        planars += kind & Lanes::splat(1);
    }
    debug_assert!(events.len() % 8 == 0);
    (starts.reduce_sum() as usize, planars.reduce_sum() as usize)
}

/// `LANES` events of a sweep (`run_masks`): bit l of each mask is about the l-th.
struct Group {
    /// Events that end their run (the last of their position).
    runs: u32,
    ends: u32,
    planar: u32,
    /// Positions (`Event::pos_bits`).
    bits: [u32; LANES],
}

/// Sorts events in sweep order: a radix sort on the key for long lists (`event_sort`), an
/// integer sort for short ones (the fresh events of most splits). Lists are made in reference
/// order, and the radix sort is stable, so both give events equal in position and kind by
/// reference, an order the build does not depend on anyway (see `event_sort`).
fn sort_events(list: &mut Vec<Event>, tmp: &mut Vec<Event>) {
    if list.len() >= event_sort::RADIX_MIN {
        event_sort::sort_by_key34(list, tmp, |e| e.key());
    } else {
        list.sort_unstable();
    }
}

fn push_events(events: &mut [Vec<Event>; 3], reference: usize, b: &Aabb) {
    for (k, list) in events.iter_mut().enumerate() {
        if b.lo[k] == b.hi[k] {
            list.push(Event::new(b.lo[k], reference, PLANAR));
        } else {
            list.push(Event::new(b.lo[k], reference, START));
            list.push(Event::new(b.hi[k], reference, END));
        }
    }
}

/// Writes into `out` (empty, with room for `cap`) the events of `old` whose reference's code has
/// the bit `keep` (`KEEP_BELOW` or `KEEP_ABOVE`), renumbered to the index in the code's low bits, merged with `fresh` (sorted)
/// in sweep order: a fresh event goes before the old events of greater key. `cap` is at least
/// one more than the events kept and fresh, or `old.len() + fresh.len()`: every event is
/// written at the next slot and counted only if kept, without a branch on that. The partition
/// of one side of a split (`Sah::split`).
fn keep_side(old: &[Event], fresh: &[Event], code: &[u32], keep: u32, out: &mut Vec<Event>, cap: usize) {
    debug_assert!(out.is_empty() && out.capacity() >= cap);
    let slots = out.spare_capacity_mut()[..cap].as_mut_ptr();
    let head = |i: usize| fresh.get(i).map_or(u64::MAX, |e| e.0);
    let (mut count, mut taken) = (0usize, 0usize);
    let mut next = head(0);
    for &Event(raw) in old {
        let floor = raw & !REFERENCE_MASK;
        while next < floor {
            debug_assert!(count < cap);
            // SAFETY: in the spare capacity, as below.
            unsafe { slots.add(count).write(MaybeUninit::new(fresh[taken])) };
            (count, taken) = (count + 1, taken + 1);
            next = head(taken);
        }
        let r = (raw & REFERENCE_MASK) as usize;
        debug_assert!(r < code.len());
        // SAFETY: a node's events refer to its references, one code each.
        let c = unsafe { *code.get_unchecked(r) };
        debug_assert!(count < cap);
        // SAFETY: `count` counts the events kept so far and the fresh ones merged, below `cap`
        // (see above).
        unsafe { slots.add(count).write(MaybeUninit::new(Event(floor | (c & INDEX) as u64))) };
        count += (c & keep != 0) as usize;
    }
    let rest = &fresh[taken..];
    assert!(count + rest.len() <= cap);
    // SAFETY: within the spare capacity (the assertion); the lists do not overlap.
    unsafe { std::ptr::copy_nonoverlapping(rest.as_ptr(), slots.add(count).cast::<Event>(), rest.len()) };
    // SAFETY: the first `count + rest.len()` slots were written, and the list was empty.
    unsafe { out.set_len(count + rest.len()) };
}

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

/// Lists kept for reuse, bucketed by capacity: bucket b holds lists whose capacity lies in
/// [2^b, 2^(b+1)). A list is handed out only to a need it covers within a factor of eight, so a
/// big list freed near the root is not held (with all its pages) by a small node deep in the
/// tree: with one unsorted pool, every pending sibling ended up holding a root-sized list and the
/// conference room's build peaked at 400 MiB.
struct Pool<T> {
    buckets: Vec<Vec<Vec<T>>>,
}

impl<T> Default for Pool<T> {
    fn default() -> Self {
        Self { buckets: (0..usize::BITS).map(|_| Vec::new()).collect() }
    }
}

impl<T> Pool<T> {
    /// An empty list with room for at least `need` items.
    fn take(&mut self, need: usize) -> Vec<T> {
        if need == 0 {
            return Vec::new();
        }
        let class = need.next_power_of_two().trailing_zeros() as usize;
        for bucket in self.buckets.iter_mut().skip(class).take(3) {
            if let Some(list) = bucket.pop() {
                return list;
            }
        }
        Vec::with_capacity(need.next_power_of_two())
    }

    fn give(&mut self, mut list: Vec<T>) {
        if list.capacity() == 0 {
            return;
        }
        list.clear();
        self.buckets[list.capacity().ilog2() as usize].push(list);
    }
}

/// Buffers a task reuses from node to node: the deep tail of the tree is millions of nodes
/// of a few references each, where allocating and freeing a dozen lists per split would cost
/// more than the split itself. Lists freed by a node go back to the pools and serve the next.
#[derive(Default)]
struct Scratch {
    event_lists: Pool<Event>,
    triangle_lists: Pool<u32>,
    code: Vec<u32>,
    fresh: [[Vec<Event>; 3]; 2],
    /// The radix sort's second buffer.
    sort: Vec<Event>,
    clip: ClipBuffers,
}

impl Scratch {
    fn events(&mut self, need: usize) -> Vec<Event> {
        self.event_lists.take(need)
    }

    fn triangles(&mut self, need: usize) -> Vec<u32> {
        self.triangle_lists.take(need)
    }

    fn recycle_events(&mut self, list: Vec<Event>) {
        self.event_lists.give(list);
    }

    fn recycle(&mut self, node: Node) {
        let Node { triangles, events, .. } = node;
        self.triangle_lists.give(triangles);
        for list in events {
            self.recycle_events(list);
        }
    }
}

#[derive(Clone, Copy, Debug)]
struct Plane {
    axis: usize,
    pos: f32,
    /// Triangles lying in the plane go below it.
    planar_below: bool,
    cost: f64,
    /// References on each side (an upper bound: perfect splits may drop a few).
    below: usize,
    above: usize,
}

/// What the cost of a plane on one axis of a voxel needs besides its position.
struct Sweep {
    /// The area of the voxel's face across the axis, and the length of that face's rim (each
    /// halved, as `Aabb::area` doubles them).
    face: f64,
    rim: f64,
    area: f64,
    lo: f32,
    hi: f32,
    /// 2·K_I / area: turns halved areas into the intersection part of the cost (in the sweep's
    /// estimate, `Sah::estimate`; the cost itself divides, as it always has).
    scale: f64,
    axis: usize,
}

/// Above this, an estimated cost (`Sah::estimate`) cannot be a plane's exact cost if that
/// beats `best`, the cheapest plane a sweep has found so far: the estimate's relative error is
/// under 2^-49.
#[inline]
fn threshold(best: &Option<Plane>) -> f64 {
    best.map_or(f64::INFINITY, |b| b.cost * (1.0 + 1e-12))
}

impl Sweep {
    /// Half the surface areas of the parts of the voxel below and above `pos`.
    #[inline]
    fn faces(&self, pos: f32) -> (f64, f64) {
        (self.face + (pos as f64 - self.lo as f64) * self.rim, self.face + (self.hi as f64 - pos as f64) * self.rim)
    }

    /// The probabilities that a ray through the voxel crosses the parts whose halved areas are
    /// `faces` (`Sweep::faces`).
    #[inline]
    fn probabilities(&self, (below_faces, above_faces): (f64, f64)) -> (f64, f64) {
        (2.0 * below_faces / self.area, 2.0 * above_faces / self.area)
    }
}

/// A subtree laid out on its own: child and index offsets are relative to its own arrays.
#[derive(Default)]
struct Subtree {
    nodes: Vec<KdNode>,
    indices: Vec<u32>,
    depth: u32,
}

/// The top of the tree as the parallel tasks built it: subtrees each laid out on its own, joined
/// by the splits above them. Written out once at the end, into arrays of the final size, so no
/// node is copied more than once whatever the number of parallel levels.
enum Part {
    Built(Subtree),
    Split { axis: u32, pos: f32, children: Box<(Part, Part)> },
}

impl Part {
    /// (nodes, indices) in all.
    fn size(&self) -> (usize, usize) {
        match self {
            Part::Built(sub) => (sub.nodes.len(), sub.indices.len()),
            Part::Split { children, .. } => {
                let ((bn, bi), (an, ai)) = (children.0.size(), children.1.size());
                (1 + bn + an, bi + ai)
            }
        }
    }

    fn write(self, out: &mut Subtree) {
        match self {
            Part::Built(sub) => out.append(sub),
            Part::Split { axis, pos, children } => {
                let (below, above) = *children;
                let me = out.nodes.len();
                out.nodes.push(KdNode::default());
                below.write(out);
                out.nodes[me] = KdNode::interior(axis, pos, out.nodes.len() as u32);
                above.write(out);
            }
        }
    }
}

impl Subtree {
    fn append(&mut self, other: Subtree) {
        let (node_base, index_base) = (self.nodes.len() as u32, self.indices.len() as u32);
        self.nodes.extend(other.nodes.into_iter().map(|n| {
            if n.is_leaf() {
                KdNode::leaf(n.first_index() + index_base, n.count())
            } else {
                KdNode::interior(n.axis(), n.split(), n.above_child() + node_base)
            }
        }));
        self.indices.extend_from_slice(&other.indices);
        self.depth = self.depth.max(other.depth);
    }

    fn leaf(&mut self, triangles: &mut [u32], depth: u32) {
        triangles.sort_unstable();
        self.nodes.push(KdNode::leaf(self.indices.len() as u32, triangles.len() as u32));
        self.indices.extend_from_slice(triangles);
        self.depth = self.depth.max(depth);
    }
}

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

/// Buffers between tasks: a task takes one set and gives it back when done, so lists freed
/// anywhere in the tree serve later nodes (memory the build has touched already, where fresh
/// pages cost a fault and zeroing each), and all of it is freed with the build. Kept apart
/// from `Sah`, which holds only the settings and the scene, so no lock sits among them.
#[derive(Default)]
struct Stash(std::sync::Mutex<Vec<Scratch>>);

impl Stash {
    /// A set of buffers from the stash, or a new one.
    fn take(&self) -> Scratch {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).pop().unwrap_or_default()
    }

    fn keep(&self, scratch: Scratch) {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).push(scratch);
    }
}

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

    /// The cheapest plane over all three axes (one sweep over each axis's sorted events).
    fn find_plane(&self, node: &Node) -> Option<Plane> {
        let voxel = &node.voxel;
        let area = voxel.area();
        if !(area > 0.0) {
            return None;
        }
        let n = node.triangles.len();
        let mut best = None;
        for (k, events) in node.events.iter().enumerate() {
            let (lo, hi) = (voxel.lo[k], voxel.hi[k]);
            let (e1, e2) = (voxel.extent((k + 1) % 3), voxel.extent((k + 2) % 3));
            let sweep = Sweep {
                face: e1 * e2,
                rim: e1 + e2,
                area,
                lo,
                hi,
                scale: 2.0 * self.intersection_cost / area,
                axis: k,
            };
            self.sweep(events, n, &sweep, &mut best);
        }
        best
    }

    /// One axis's sweep (Wald & Havran §5.1): the candidates are the positions of the events,
    /// each priced with the references wholly below it, in it, and wholly above it.
    fn sweep(&self, events: &[Event], n: usize, sweep: &Sweep, best: &mut Option<Plane>) {
        // SAFETY: `Event` is a `repr(transparent)` u64.
        let raw: &[u64] = unsafe { std::slice::from_raw_parts(events.as_ptr().cast::<u64>(), events.len()) };
        // Ends and planars before the current group, and planars up to the last run.
        let (mut ends_before, mut planar_before, mut planar_done) = (0usize, 0usize, 0usize);
        let mut below = 0usize;
        let mut threshold = self::threshold(best);
        #[cfg(test)]
        let mut check = SweepCheck::default();
        let mut first = 0;
        while first < raw.len() {
            #[cfg(test)]
            check.state(raw, first, (ends_before, planar_before, below, planar_done));
            if first % BLOCK == 0 && threshold < f64::INFINITY && first + BLOCK < raw.len() {
                // A block of groups, screened as a group is but from its first and last events
                // and the counts of its kinds alone: passed over whole, it costs a sum of
                // kinds and a binary search for its last run end instead of four groups'
                // masks.
                let block = &raw[first..first + BLOCK];
                let (starts, planars) = kind_counts(block);
                let least_above = n - (ends_before + planar_before + BLOCK - starts);
                let special = (planars != 0) | (planar_before != planar_done) | (below == 0) | (least_above == 0);
                let bound = self.screened(
                    self.estimate_between(
                        sweep,
                        Event(block[0]).pos_bits(),
                        Event(block[BLOCK - 1]).pos_bits(),
                        below,
                        least_above,
                    ),
                    special,
                );
                if bound > threshold {
                    #[cfg(test)]
                    check.passed_over(self, raw, n, sweep, first + BLOCK, threshold);
                    // The events after the block's last run end belong to a run that goes on,
                    // at the position of the event after the block; sorted by kind within it,
                    // they are found by binary search (a run can be thousands of events long
                    // where walls lie in a plane).
                    let next = raw[first + BLOCK] >> 32 << 32;
                    let (last, tail_ends, tail_planars) = if block[BLOCK - 1] < next {
                        (BLOCK, 0, 0)
                    } else {
                        let at = |kind: u32| block.partition_point(|&e| e < next | (kind as u64) << REFERENCE_BITS);
                        let (tail, planar_tail, start_tail) = (at(END), at(PLANAR), at(START));
                        (tail, planar_tail - tail, start_tail - planar_tail)
                    };
                    let (ends_block, planar_block) = (BLOCK - starts - planars, planars);
                    if last > 0 {
                        // `last` events up to and including the last run end.
                        let ends_here = ends_before + ends_block - tail_ends;
                        below = first + last - ends_here;
                        planar_done = planar_before + planar_block - tail_planars;
                    }
                    ends_before += ends_block;
                    planar_before += planar_block;
                    first += BLOCK;
                    continue;
                }
            }
            let Group { mut runs, ends, planar: planars, bits } = run_masks(raw, first);
            let (ends_after, planar_after) =
                (ends_before + ends.count_ones() as usize, planar_before + planars.count_ones() as usize);
            if runs != 0 && threshold < f64::INFINITY {
                // Every run ending in the group has at least `below` references below and
                // `n - ends_after - planar_after` above, and lies between the first and the
                // last run end: the estimate with the faces and counts at their least bounds
                // every run's estimate from below (rounding is monotonic, as is each term), so
                // when even that lies above the threshold, no run of the group can pass it.
                let last = 31 - runs.leading_zeros() as usize;
                let least_above = n - ends_after - planar_after;
                // A run with planar references (this group's, or an unfinished run's from the
                // last group) or an empty side is screened by its estimate times the smaller λ.
                let special = (planars != 0) | (planar_before != planar_done) | (below == 0) | (least_above == 0);
                let bound = self.screened(
                    self.estimate_between(sweep, bits[runs.trailing_zeros() as usize], bits[last], below, least_above),
                    special,
                );
                if bound > threshold {
                    #[cfg(test)]
                    check.passed_over(self, raw, n, sweep, first + LANES, threshold);
                    let upto = (2u32 << last).wrapping_sub(1);
                    let ends_here = ends_before + (ends & upto).count_ones() as usize;
                    below = first + last + 1 - ends_here;
                    planar_done = planar_before + (planars & upto).count_ones() as usize;
                    runs = 0;
                }
            }
            while runs != 0 {
                // Sorted by position and then kind, so a run holds every event at its position.
                let l = runs.trailing_zeros() as usize;
                runs &= runs - 1;
                let upto = (2u32 << l).wrapping_sub(1);
                let ends_here = ends_before + (ends & upto).count_ones() as usize;
                let planar_here = planar_before + (planars & upto).count_ones() as usize;
                let planar = planar_here - planar_done;
                let above = n - ends_here - planar_here;
                let bits = bits[l];
                // Planes with planar references or an empty side take `evaluate`'s cases: λ may
                // scale their cost, and the planar references add to one side, so the estimate
                // with the references wholly on each side, times the smaller λ, bounds them from
                // below.
                let special = (planar != 0) | (below == 0) | (above == 0);
                let bound = self.screened(self.estimate(sweep, bits, below, above), special);
                if bound <= threshold {
                    self.consider(sweep, bits, below, planar, above, best);
                    threshold = self::threshold(best);
                }
                // Every event so far is an end, a planar or a start; the latter two are below
                // the next position.
                below = first + l + 1 - ends_here;
                planar_done = planar_here;
            }
            (ends_before, planar_before) = (ends_after, planar_after);
            first += LANES;
        }
    }

    /// The cost of a plane with nothing in it and neither side empty, estimated with a
    /// multiply where the cost divides: within a few roundings of positive terms (relative
    /// error under 2^-49) of `consider`'s exact cost. The exact cost takes two divisions, whose
    /// latency was a quarter of the sweep; a plane whose estimate lies clearly above the best so
    /// far (`threshold`) cannot beat it, so only the rest pay for the exact cost, which
    /// alone decides. For any other plane, the estimate with `below` and `above` the references
    /// wholly on each side bounds every placement's cost from below once scaled by λ.
    #[inline]
    fn estimate(&self, s: &Sweep, bits: u32, below: usize, above: usize) -> f64 {
        let (below_faces, above_faces) = s.faces(event_sort::position_of(bits));
        self.traversal_cost + s.scale * (below_faces * self.leaf_tests(below) + above_faces * self.leaf_tests(above))
    }

    /// What an estimate is screened by: the estimate itself for a plain plane, times the smaller
    /// λ for a `special` one (planar references or an empty side), whose placements `evaluate`
    /// weighs and which this bounds from below.
    #[inline]
    fn screened(&self, estimate: f64, special: bool) -> f64 {
        if special {
            estimate * self.empty_factor.min(1.0)
        } else {
            estimate
        }
    }

    /// `estimate` with the face below the plane at `low` and the face above it at `high`: no
    /// more than the estimate of any plane between them with at least `below` and `above`
    /// references on each side.
    #[inline]
    fn estimate_between(&self, s: &Sweep, low: u32, high: u32, below: usize, above: usize) -> f64 {
        let (below_faces, _) = s.faces(event_sort::position_of(low));
        let (_, above_faces) = s.faces(event_sort::position_of(high));
        self.traversal_cost + s.scale * (below_faces * self.leaf_tests(below) + above_faces * self.leaf_tests(above))
    }

    /// Takes the plane at `bits` if it is cheaper than the best so far (the first of equals
    /// wins): the exact cost, whatever an estimate said.
    #[inline]
    fn consider(&self, s: &Sweep, bits: u32, below: usize, planar: usize, above: usize, best: &mut Option<Plane>) {
        let pos = event_sort::position_of(bits);
        let found = if planar == 0 && below > 0 && above > 0 {
            // λ = 1, and the plane lies inside the voxel: `evaluate` without its cases (and
            // the same cost, bit for bit).
            let (p_below, p_above) = s.probabilities(s.faces(pos));
            Some((
                self.traversal_cost
                    + self.intersection_cost * (p_below * self.leaf_tests(below) + p_above * self.leaf_tests(above)),
                true,
            ))
        } else {
            self.evaluate(s, pos, below, planar, above)
        };
        if let Some((cost, planar_below)) = found {
            if best.is_none_or(|b| cost < b.cost) {
                let (nb, na) = if planar_below { (below + planar, above) } else { (below, above + planar) };
                *best = Some(Plane { axis: s.axis, pos, planar_below, cost, below: nb, above: na });
            }
        }
    }

    /// The cost of splitting at `pos` with the planar triangles on the cheaper side, and whether
    /// that side is below; `None` for a split that makes no progress (an empty child whose
    /// sibling is the voxel).
    #[inline]
    fn evaluate(&self, s: &Sweep, pos: f32, below: usize, planar: usize, above: usize) -> Option<(f64, bool)> {
        let (p_below, p_above) = s.probabilities(s.faces(pos));
        let flat_on_boundary = pos == s.lo || pos == s.hi;
        let cost = |nb: usize, na: usize| -> Option<f64> {
            if (nb == 0 && pos == s.lo) || (na == 0 && pos == s.hi) {
                return None;
            }
            let lambda = if (nb == 0 || na == 0) && !flat_on_boundary { self.empty_factor } else { 1.0 };
            Some(
                lambda
                    * (self.traversal_cost
                        + self.intersection_cost * (p_below * self.leaf_tests(nb) + p_above * self.leaf_tests(na))),
            )
        };
        if planar == 0 {
            // Both placements are the same split; ties go below.
            return cost(below, above).map(|c| (c, true));
        }
        match (cost(below + planar, above), cost(below, above + planar)) {
            (Some(b), Some(a)) => Some(if b <= a { (b, true) } else { (a, false) }),
            (Some(b), None) => Some((b, true)),
            (None, Some(a)) => Some((a, false)),
            (None, None) => None,
        }
    }

    /// A split with every reference on one side (the λ rule cutting off empty space, about half
    /// the splits of a mesh's tree): nothing straddles, and the references keep their order and
    /// numbering, so that side's child takes the node's lists as they are.
    fn cut_off_empty(node: Node, plane: Plane, bad_refines: u32) -> (Node, Node) {
        let Node { triangles, events, voxel, depth, bad_refines: _, budget } = node;
        let (below_voxel, above_voxel) = voxel.split(plane.axis, plane.pos);
        let depth = depth + 1;
        // The same share as `split` gives, computed the same way. The empty child is a leaf
        // before its budget is read (no references), so it gets none.
        let refs = triangles.len().max(1) as f64;
        let full = budget * triangles.len() as f64 / refs;
        let empty = 0.0;
        let full_node = |voxel| Node { triangles, events, voxel, depth, bad_refines, budget: full };
        let empty_node = |voxel| Node {
            triangles: Vec::new(),
            events: Default::default(),
            voxel,
            depth,
            bad_refines,
            budget: empty,
        };
        if plane.below == 0 {
            (empty_node(below_voxel), full_node(above_voxel))
        } else {
            (full_node(below_voxel), empty_node(above_voxel))
        }
    }

    /// Partitions the node's references and events for `plane` (Wald & Havran §5.3).
    fn split(&self, node: Node, plane: Plane, bad_refines: u32, scratch: &mut Scratch) -> (Node, Node) {
        // One code per reference (`STRADDLES`, `KEEP_BELOW`, `KEEP_ABOVE`, `INDEX`). The
        // partition adds the keep bits to the children's counts as they are, with no
        // comparisons.
        let (k, pos) = (plane.axis, plane.pos);
        let pos_bits = event_sort::ordered_bits(pos);
        if plane.below == 0 || plane.above == 0 {
            return Self::cut_off_empty(node, plane, bad_refines);
        }
        let n = node.triangles.len();
        let mut code = std::mem::take(&mut scratch.code);
        code.clear();
        code.resize(n, STRADDLES);
        // An end at or below the plane keeps its reference below, a start at or above keeps it
        // above, and a planar event keeps its reference on the side the plane chose for it. No
        // reference gets both bits: its start lies below its end, so they cannot lie above and
        // below the plane. The list is in sweep order, so these are ranges of it, found by
        // binary search: before the planars at the plane, every event that is not a start
        // keeps its reference below; from the starts at the plane on, every event that is not an
        // end keeps it above; in between, the planars at the plane go to the chosen side. Each
        // event then costs a load, two bit operations and a store, with no comparison of
        // positions (kinds come in no predictable order, so each is a bit operation, not a
        // branch).
        let (planars, starts) = {
            let events = &node.events[k];
            let at = |kind: u32| {
                events.partition_point(|e| e.0 < ((pos_bits as u64) << 32 | (kind as u64) << REFERENCE_BITS))
            };
            let (planars, starts) = (at(PLANAR), at(START));
            fn mark(range: &[Event], code: &mut [u32], bit: impl Fn(u32) -> u32) {
                for e in range {
                    debug_assert!(e.reference() < code.len());
                    // SAFETY: a node's events refer to its references, one code each.
                    unsafe { *code.get_unchecked_mut(e.reference()) |= bit(e.0 as u32) };
                }
            }
            // The kind's bits: an end has neither, a planar bit 30, a start bit 31.
            mark(&events[..planars], &mut code, |low| (!low >> 1) & KEEP_BELOW);
            let side = if plane.planar_below { KEEP_BELOW } else { KEEP_ABOVE };
            mark(&events[planars..starts], &mut code, |_| side);
            mark(&events[starts..], &mut code, |low| (low | low << 1) & KEEP_ABOVE);
            (planars, starts)
        };
        let (below_voxel, above_voxel) = node.voxel.split(k, pos);
        // A child that `decide` will make a leaf before looking at its events (too few
        // references, or at the depth limit) gets none: over a third of the children are such.
        let depth = node.depth + 1;
        let need = [plane.below, plane.above].map(|count| count > self.leaf_size && depth < self.max_depth);
        // Room for one more than each side can hold (`Plane::below`, `Plane::above` bound the
        // references, straddlers included): a reference is written to both lists and counted
        // in its own, without a branch on the side.
        let mut tris: [Vec<u32>; 2] = [scratch.triangles(plane.below + 1), scratch.triangles(plane.above + 1)];
        let mut fresh = std::mem::take(&mut scratch.fresh);
        {
            let caps = [plane.below + 1, plane.above + 1];
            let [below_tris, above_tris] = &mut tris;
            let lists = [
                below_tris.spare_capacity_mut()[..caps[0]].as_mut_ptr(),
                above_tris.spare_capacity_mut()[..caps[1]].as_mut_ptr(),
            ];
            let mut counts = [0usize; 2];
            for r in 0..n {
                // A straddler's vertices are read from the scene, at random: fetch them ahead.
                if code.get(r + PREFETCH_AHEAD) == Some(&STRADDLES) {
                    prefetch(&self.triangles[node.triangles[r + PREFETCH_AHEAD] as usize]);
                }
                let c = code[r];
                let t = node.triangles[r];
                if c == STRADDLES {
                    // Clipped to each child (perfect splits); a child it misses drops it.
                    let tri = to_f64(&self.triangles[t as usize]);
                    let boxes = split_boxes(&tri, &node.voxel, k, pos, &mut scratch.clip).unwrap_or_else(|| {
                        [below_voxel, above_voxel].map(|voxel| clipped_box_with(&tri, &voxel, &mut scratch.clip))
                    });
                    for (s, b) in boxes.iter().enumerate() {
                        if let Some(b) = b {
                            if need[s] {
                                push_events(&mut fresh[s], counts[s], b);
                            }
                            assert!(counts[s] < caps[s]);
                            // SAFETY: within the spare capacity (the assertion).
                            unsafe { lists[s].add(counts[s]).write(MaybeUninit::new(t)) };
                            counts[s] += 1;
                        }
                    }
                } else {
                    let above = (c & KEEP_ABOVE != 0) as usize;
                    let index = if above != 0 { counts[1] } else { counts[0] };
                    debug_assert!(index as u32 <= INDEX);
                    code[r] = c | index as u32;
                    // Each count stays below its side's bound, so both slots lie within the
                    // spare capacities (one past the bound at most for the side not taken).
                    debug_assert!(counts[0] < caps[0] && counts[1] < caps[1]);
                    // SAFETY: as just said.
                    unsafe {
                        lists[0].add(counts[0]).write(MaybeUninit::new(t));
                        lists[1].add(counts[1]).write(MaybeUninit::new(t));
                    }
                    counts[0] += 1 - above;
                    counts[1] += above;
                }
            }
            // SAFETY: slots below each count were written (each written slot is rewritten until
            // its count moves past it), and the lists were empty.
            unsafe {
                below_tris.set_len(counts[0]);
                above_tris.set_len(counts[1]);
            }
        }
        let mut events: [[Vec<Event>; 3]; 2] = Default::default();
        let Node {
            triangles: old_triangles,
            events: [old_x, old_y, old_z],
            voxel: _,
            depth: _,
            bad_refines: _,
            budget,
        } = node;
        for (axis, old) in [old_x, old_y, old_z].into_iter().enumerate() {
            for side in &mut fresh {
                if !side[axis].is_empty() {
                    sort_events(&mut side[axis], &mut scratch.sort);
                }
            }
            let (fresh_below, fresh_above) = (&fresh[0][axis], &fresh[1][axis]);
            // A child holds at most two events per reference on each axis; the partition below
            // writes one slot past the events it keeps.
            let (cap_b, cap_a) = (
                (old.len() + fresh_below.len()).min(2 * tris[0].len() + 1),
                (old.len() + fresh_above.len()).min(2 * tris[1].len() + 1),
            );
            let (mut below, mut above) =
                (scratch.events(if need[0] { cap_b } else { 0 }), scratch.events(if need[1] { cap_a } else { 0 }));
            // On the split axis, the events below the starts at the plane keep references
            // below or none, and those from the planars at it on keep them above or none: each
            // side is partitioned on its own, one store an event.
            let split_axis = axis == k;
            let (range_below, range_above) =
                if split_axis { (&old[..starts], &old[planars..]) } else { (&old[..], &old[..]) };
            match need {
                [true, true] if split_axis => {
                    keep_side(range_below, fresh_below, &code, KEEP_BELOW, &mut below, cap_b);
                    keep_side(range_above, fresh_above, &code, KEEP_ABOVE, &mut above, cap_a);
                }
                [true, true] => {
                    // Every event is written to both lists and kept by the side it belongs to:
                    // the side is as good as random in the large nodes, where a branch on it
                    // mispredicts. The lists are written into their spare capacity, not zeroed
                    // to the parent's length first: only the slots a child keeps (and one past)
                    // are touched (the zeroing was half of the build's page faults). The
                    // straddlers' fresh events, sorted, are merged in on the way, each after
                    // the old events of its key (as `keep_side` places them): one pass instead
                    // of a partition and a merge that moves half of each list.
                    // The pools handed out empty lists of at least these capacities.
                    debug_assert!(below.is_empty() && above.is_empty());
                    let (mut nb, mut na, mut ib, mut ia) = (0, 0, 0, 0);
                    // A fresh event goes first while it is below the old event's key floor, that
                    // is while its key is smaller (events of one key differ in references only).
                    let head_key = |list: &[Event], i: usize| list.get(i).map_or(u64::MAX, |e| e.0);
                    let (mut kb, mut ka) = (head_key(fresh_below, 0), head_key(fresh_above, 0));
                    // The smaller of the two: the one comparison an old event needs.
                    let mut next = kb.min(ka);
                    {
                        let (bs, as_) = (
                            below.spare_capacity_mut()[..cap_b].as_mut_ptr(),
                            above.spare_capacity_mut()[..cap_a].as_mut_ptr(),
                        );
                        let codes = &code[..n];
                        for &Event(raw) in &old {
                            let floor = raw & !REFERENCE_MASK;
                            if next < floor {
                                while kb < floor {
                                    debug_assert!(nb < cap_b);
                                    // SAFETY: in the spare capacity, as below.
                                    unsafe { bs.add(nb).write(MaybeUninit::new(fresh_below[ib])) };
                                    (nb, ib) = (nb + 1, ib + 1);
                                    kb = head_key(fresh_below, ib);
                                }
                                while ka < floor {
                                    debug_assert!(na < cap_a);
                                    // SAFETY: in the spare capacity, as below.
                                    unsafe { as_.add(na).write(MaybeUninit::new(fresh_above[ia])) };
                                    (na, ia) = (na + 1, ia + 1);
                                    ka = head_key(fresh_above, ia);
                                }
                                next = kb.min(ka);
                            }
                            let r = (raw & REFERENCE_MASK) as usize;
                            debug_assert!(r < n);
                            // SAFETY: a node's events refer to its references, 0..n.
                            let c = unsafe { *codes.get_unchecked(r) };
                            let m = Event(floor | (c & INDEX) as u64);
                            // nb and na count the events kept so far, which the capacities
                            // exceed (`cap_b`, `cap_a`).
                            debug_assert!(nb < cap_b && na < cap_a);
                            // SAFETY: the slots lie in the lists' spare capacities (above).
                            unsafe {
                                bs.add(nb).write(MaybeUninit::new(m));
                                as_.add(na).write(MaybeUninit::new(m));
                            }
                            nb += (c & KEEP_BELOW != 0) as usize;
                            na += (c & KEEP_ABOVE != 0) as usize;
                        }
                        // SAFETY: the rest of each fresh list fits in the capacity it was counted in.
                        unsafe {
                            debug_assert!(nb + fresh_below.len() - ib <= cap_b && na + fresh_above.len() - ia <= cap_a);
                            std::ptr::copy_nonoverlapping(
                                fresh_below[ib..].as_ptr(),
                                bs.add(nb).cast::<Event>(),
                                fresh_below.len() - ib,
                            );
                            std::ptr::copy_nonoverlapping(
                                fresh_above[ia..].as_ptr(),
                                as_.add(na).cast::<Event>(),
                                fresh_above.len() - ia,
                            );
                        }
                        nb += fresh_below.len() - ib;
                        na += fresh_above.len() - ia;
                    }
                    // SAFETY: the loops wrote slots 0..nb of `below` and 0..na of `above` (each
                    // kept event's slot is written before its count moves past it), and both
                    // lists were empty, so their first nb and na elements are initialised.
                    unsafe {
                        below.set_len(nb);
                        above.set_len(na);
                    }
                }
                [true, false] => keep_side(range_below, fresh_below, &code, KEEP_BELOW, &mut below, cap_b),
                [false, true] => keep_side(range_above, fresh_above, &code, KEEP_ABOVE, &mut above, cap_a),
                [false, false] => {}
            }
            scratch.recycle_events(old);
            for side in &mut fresh {
                side[axis].clear();
            }
            events[0][axis] = below;
            events[1][axis] = above;
        }
        scratch.code = code;
        scratch.fresh = fresh;
        let mut old_triangles = old_triangles;
        old_triangles.clear();
        scratch.triangle_lists.give(old_triangles);
        let [below_tris, above_tris] = tris;
        let [below_events, above_events] = events;
        // The budget follows the references: each child gets its share, so no subtree can take
        // more than the root allowed in all.
        let refs = (below_tris.len() + above_tris.len()).max(1) as f64;
        let (below_budget, above_budget) =
            (budget * below_tris.len() as f64 / refs, budget * above_tris.len() as f64 / refs);
        (
            Node {
                triangles: below_tris,
                events: below_events,
                voxel: below_voxel,
                depth,
                bad_refines,
                budget: below_budget,
            },
            Node {
                triangles: above_tris,
                events: above_events,
                voxel: above_voxel,
                depth,
                bad_refines,
                budget: above_budget,
            },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sweep as Wald & Havran state it: every run priced exactly (`evaluate`), the first
    /// cheapest kept. What `Sah::sweep` must choose, bit for bit, with its estimates and its
    /// event-group masks and skipped groups.
    fn plain_sweep(sah: &Sah, events: &[Event], n: usize, sweep: &Sweep, best: Option<Plane>) -> Option<Plane> {
        let (mut best, mut below, mut above, mut i): (Option<Plane>, usize, usize, usize) = (best, 0, n, 0);
        while i < events.len() {
            let bits = events[i].pos_bits();
            let mut count = [0usize; 3];
            while i < events.len() && events[i].pos_bits() == bits {
                count[events[i].kind() as usize] += 1;
                i += 1;
            }
            let planar = count[PLANAR as usize];
            above -= count[END as usize] + planar;
            let pos = event_sort::position_of(bits);
            if let Some((cost, planar_below)) = sah.evaluate(sweep, pos, below, planar, above) {
                if best.is_none_or(|b| cost < b.cost) {
                    let (nb, na) = if planar_below { (below + planar, above) } else { (below, above + planar) };
                    best = Some(Plane { axis: sweep.axis, pos, planar_below, cost, below: nb, above: na });
                }
            }
            below += count[START as usize] + planar;
        }
        best
    }

    /// Random lists with many shared positions, planar references and both empty ends, from
    /// one event to hundreds (the masks' tail and full groups), for three leaf widths.
    #[test]
    fn sweep_chooses_the_plain_sweeps_plane() {
        let mut next = crate::kdbuild::xorshift(0x2545_f491_4f6c_dd1d);
        let mut compared = 0;
        for trial in 0..3000 {
            let leaf_block = [1usize, 8, 3][trial % 3];
            let sah = Sah {
                triangles: &[],
                traversal_cost: 15.0,
                intersection_cost: 4.0,
                leaf_block: LeafTests::new(leaf_block),
                empty_factor: 0.8,
                max_depth: 30,
                leaf_size: 1,
                bad_refines: 2,
            };
            let n = 1 + (next() % [4, 40, 400, 3000][trial % 7 % 4]) as usize;
            // Few positions make long runs across groups and blocks; many make short ones.
            let levels = 1 + next() % [12, 12, 1000][trial % 5 % 3];
            let (lo, hi) = (0.0f32, levels as f32);
            let mut events = Vec::new();
            for r in 0..n {
                let a = (next() % (levels + 1)) as f32;
                let b = if next() % 4 == 0 { a } else { (next() % (levels + 1)) as f32 };
                let (s0, s1) = (a.min(b), a.max(b));
                if s0 == s1 {
                    events.push(Event::new(s0, r, PLANAR));
                } else {
                    events.push(Event::new(s0, r, START));
                    events.push(Event::new(s1, r, END));
                }
            }
            sort_events(&mut events, &mut Vec::new());
            let (e1, e2) = (1.0 + (next() % 5) as f64, 0.5 + (next() % 3) as f64);
            let area = 2.0 * (e1 * e2 + (e1 + e2) * (hi - lo) as f64);
            let sweep = Sweep {
                face: e1 * e2,
                rim: e1 + e2,
                area,
                lo,
                hi,
                scale: 2.0 * sah.intersection_cost / area,
                axis: trial % 3,
            };
            let want = plain_sweep(&sah, &events, n, &sweep, None);
            let mut best = None;
            sah.sweep(&events, n, &sweep, &mut best);
            let key = |p: Option<Plane>| {
                p.map(|p| (p.axis, p.pos.to_bits(), p.planar_below, p.cost.to_bits(), p.below, p.above))
            };
            assert_eq!(key(best), key(want), "trial {trial}: {n} references, leaf block {leaf_block}");
            compared += want.is_some() as usize;
            // The same events on a second axis whose faces are a hair smaller: every plane there
            // is a little cheaper than its twin on the first axis, so its best wins by a margin
            // far below what separates neighbouring planes, and the groups and blocks that
            // hold it are screened against a threshold just above their least cost. A bound
            // that overshoots by a single leaf test passes it over.
            let narrower = e1 * (1.0 - 1e-9);
            let twin = Sweep { face: narrower * e2, rim: narrower + e2, axis: (trial + 1) % 3, ..sweep };
            let want = plain_sweep(&sah, &events, n, &twin, want);
            sah.sweep(&events, n, &twin, &mut best);
            assert_eq!(key(best), key(want), "trial {trial}, second axis: {n} references, leaf block {leaf_block}");
        }
        assert!(compared > 2000, "only {compared} sweeps found a plane");
    }

    /// A pool hands out a list that covers the need, never one more than eight times too big
    /// (the bound that keeps root-sized lists away from deep nodes), and reuses what it got.
    #[test]
    fn pool_hands_out_lists_that_fit_the_need() {
        let mut pool: Pool<u32> = Pool::default();
        assert_eq!(pool.take(0).capacity(), 0, "an empty need allocates nothing");
        let big: Vec<u32> = Vec::with_capacity(1 << 20);
        let big_ptr = big.as_ptr();
        pool.give(big);
        for need in [1usize, 100, 5000, (1 << 16) + 1] {
            let list = pool.take(need);
            assert!(list.capacity() >= need && list.is_empty());
            assert!(list.capacity() <= 16 * need.next_power_of_two(), "need {need} got a list of {}", list.capacity());
            assert_ne!(list.as_ptr(), big_ptr, "need {need} was given the root-sized list");
        }
        // Within a factor of eight the big list is reused, not a new one allocated.
        let reused = pool.take((1 << 18) + 1);
        assert_eq!(reused.as_ptr(), big_ptr);
        let mut small = pool.take(10);
        small.extend([1, 2, 3]);
        let small_ptr = small.as_ptr();
        pool.give(small);
        let again = pool.take(9);
        assert_eq!((again.as_ptr(), again.len()), (small_ptr, 0), "a given list comes back cleared");
    }

    /// The integer sort of short lists and the radix sort of long ones both give the sweep
    /// order: by position (IEEE total order), then kind.
    #[test]
    fn sort_events_follows_the_sweep_order() {
        let mut next = crate::kdbuild::xorshift(12345);
        let mut tmp = Vec::new();
        for n in [0usize, 3, 100, event_sort::RADIX_MIN + 7, 5000] {
            let mut list: Vec<Event> = (0..n)
                .map(|r| {
                    Event::new(
                        [-2.0f32, -0.0, 0.0, 0.5, 3.0][next() as usize % 5] * (1 + next() % 3) as f32,
                        r,
                        (next() % 3) as u32,
                    )
                })
                .collect();
            let mut want = list.clone();
            want.sort_by(|a, b| a.pos().total_cmp(&b.pos()).then(a.kind().cmp(&b.kind())));
            sort_events(&mut list, &mut tmp);
            assert!(list.windows(2).all(|w| w[0].key() <= w[1].key()), "n {n}: not sorted");
            assert!(
                list.iter().zip(&want).all(|(a, b)| a.pos().to_bits() == b.pos().to_bits() && a.kind() == b.kind()),
                "n {n}: not in the sweep order"
            );
            let key = |e: &Event| e.0;
            let (mut a, mut b): (Vec<_>, Vec<_>) = (list.iter().map(key).collect(), want.iter().map(key).collect());
            a.sort();
            b.sort();
            assert_eq!(a, b, "n {n}: not the same events");
        }
    }
}
