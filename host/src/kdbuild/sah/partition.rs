//! The partition of a node for its split (Wald & Havran 2006, "On building fast kd-Trees for Ray
//! Tracing, and on doing that in O(N log N)", §5.3): each reference is classified once from the
//! split axis's events (below, above, or straddling), the references and every axis's events
//! follow that classification in one pass each and keep their sweep order, and only the
//! straddlers get events anew, from their boxes clipped to each child (perfect splits, §4.3),
//! sorted and merged in on the way. No list is sorted again: O(N) a split.
//!
//! These passes run over every event of every split, so they are branch-free where the side is
//! as good as random: an item is written to both children's lists and counted only in its own. A split
//! that cuts off empty space (`cut_off_empty`) hands the node's lists to the full child as they
//! are, and a child that will be a leaf gets no events.
use super::event::{push_events, sort_events, Event, PLANAR, REFERENCE_BITS, REFERENCE_MASK, START};
use super::stash::Scratch;
use super::sweep::Plane;
use super::{Node, Sah};
use crate::kdbuild::clip::{clipped_box_with, split_boxes, to_f64};
use crate::kdbuild::event_sort;
use std::mem::MaybeUninit;

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

/// One child's part in the partition of an event list (`keep_sides`): the fresh events of the
/// straddlers (sorted), the bit its references' codes carry (`KEEP_BELOW` or `KEEP_ABOVE`), and
/// its list, empty and with room for `cap` events. `cap` is at least one more than the events
/// kept and fresh, or the old and fresh events in all: every old event is written at the next
/// slot and counted only if kept, without a branch on that.
struct Side<'a> {
    fresh: &'a [Event],
    keep: u32,
    out: &'a mut Vec<Event>,
    cap: usize,
}

/// Writes into each side's list the events of `old` whose reference's code has the side's keep
/// bit, renumbered to the index in the code's low bits, merged with the side's fresh events in
/// sweep order: a fresh event goes before the old events of greater key. One pass over `old`
/// for `S` sides: one side where its range of the list holds only events it keeps or drops (the
/// split axis), or both where every event may go either way (the other axes), each event then
/// written to both lists and kept by its own side: that side is as good as random in the large
/// nodes, where a branch on it mispredicts. The lists are written in their spare capacity, not
/// zeroed to the parent's length first: only the slots a child keeps (and one past) are touched
/// (the zeroing was half of the build's page faults).
#[inline(always)]
fn keep_sides<const S: usize>(old: &[Event], code: &[u32], sides: [Side<'_>; S]) {
    let fresh = sides.each_ref().map(|side| side.fresh);
    let keep = sides.each_ref().map(|side| side.keep);
    let caps = sides.each_ref().map(|side| side.cap);
    let mut outs = sides.map(|side| side.out);
    // The pools handed out empty lists of at least these capacities.
    debug_assert!((0..S).all(|s| outs[s].is_empty() && outs[s].capacity() >= caps[s]));
    let slots: [*mut MaybeUninit<Event>; S] =
        std::array::from_fn(|s| outs[s].spare_capacity_mut()[..caps[s]].as_mut_ptr());
    // The key of each side's next fresh event, `u64::MAX` past the last. A fresh event goes first
    // while it is below the old event's key floor, that is while its key is smaller (events of
    // one key differ in references only).
    let head = |list: &[Event], i: usize| list.get(i).map_or(u64::MAX, |e| e.0);
    let (mut count, mut taken) = ([0usize; S], [0usize; S]);
    let mut heads = fresh.map(|list| head(list, 0));
    // The least of the heads: the one comparison an old event needs.
    let least = |heads: &[u64; S]| heads.iter().fold(u64::MAX, |a, &b| a.min(b));
    let mut next = least(&heads);
    for &Event(raw) in old {
        let floor = raw & !REFERENCE_MASK;
        if next < floor {
            for s in 0..S {
                while heads[s] < floor {
                    debug_assert!(count[s] < caps[s]);
                    // SAFETY: in the spare capacity, as below.
                    unsafe { slots[s].add(count[s]).write(MaybeUninit::new(fresh[s][taken[s]])) };
                    (count[s], taken[s]) = (count[s] + 1, taken[s] + 1);
                    heads[s] = head(fresh[s], taken[s]);
                }
            }
            next = least(&heads);
        }
        let r = (raw & REFERENCE_MASK) as usize;
        debug_assert!(r < code.len());
        // SAFETY: a node's events refer to its references, one code each.
        let c = unsafe { *code.get_unchecked(r) };
        let moved = Event(floor | (c & INDEX) as u64);
        for s in 0..S {
            // The count is of the events kept so far and the fresh ones merged, which the
            // capacity exceeds (see `Side`).
            debug_assert!(count[s] < caps[s]);
            // SAFETY: the slot lies in the list's spare capacity (as just said).
            unsafe { slots[s].add(count[s]).write(MaybeUninit::new(moved)) };
            count[s] += (c & keep[s] != 0) as usize;
        }
    }
    for s in 0..S {
        let rest = &fresh[s][taken[s]..];
        assert!(count[s] + rest.len() <= caps[s]);
        // SAFETY: within the spare capacity (the assertion); the lists do not overlap.
        unsafe { std::ptr::copy_nonoverlapping(rest.as_ptr(), slots[s].add(count[s]).cast::<Event>(), rest.len()) };
        // SAFETY: the pass wrote the first `count` slots (each kept event's slot is written
        // before its count moves past it), the copy the rest, and the list was empty.
        unsafe { outs[s].set_len(count[s] + rest.len()) };
    }
}

impl Sah<'_> {
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
    pub(super) fn split(&self, node: Node, plane: Plane, bad_refines: u32, scratch: &mut Scratch) -> (Node, Node) {
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
            let below_side = |out| Side { fresh: fresh_below, keep: KEEP_BELOW, out, cap: cap_b };
            let above_side = |out| Side { fresh: fresh_above, keep: KEEP_ABOVE, out, cap: cap_a };
            match need {
                [true, true] if split_axis => {
                    keep_sides(range_below, &code, [below_side(&mut below)]);
                    keep_sides(range_above, &code, [above_side(&mut above)]);
                }
                [true, true] => keep_sides(&old, &code, [below_side(&mut below), above_side(&mut above)]),
                [true, false] => keep_sides(range_below, &code, [below_side(&mut below)]),
                [false, true] => keep_sides(range_above, &code, [above_side(&mut above)]),
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
