//! Events, the unit of work of the build: a triangle's box becomes a start and an end on each
//! axis, or one planar event where it is flat on that axis (Wald & Havran 2006, "On building
//! fast kd-Trees for Ray Tracing, and on doing that in O(N log N)", §5.1). Each node keeps one
//! list per axis in sweep order, by position and then kind (end < planar < start), so the sweep
//! (`sweep`) meets every candidate plane in order and the partition (`partition`) keeps that
//! order without sorting again (§5.3).
//!
//! An event is one integer whose order is the sweep order, so sorting, merging and classifying
//! events compare integers; this file holds its encoding, the sort, and the making of a box's
//! events.
use crate::kdbuild::clip::Aabb;
use crate::kdbuild::event_sort;

pub(super) const END: u32 = 0;
pub(super) const PLANAR: u32 = 1;
pub(super) const START: u32 = 2;

/// Bits of an event that hold its node-local reference (scenes have fewer than 2^30 triangles).
pub(super) const REFERENCE_BITS: u32 = 30;
pub(super) const REFERENCE_MASK: u64 = (1 << REFERENCE_BITS) - 1;

/// One event, packed into one integer whose order is the sweep's: the position as
/// `event_sort::ordered_bits` (bits 32–63, an unsigned integer in the float's order), the kind
/// (bits 30–31: end < planar < start, Wald & Havran §5.1) and the node-local reference
/// (bits 0–29). Comparing, sorting and merging events are then integer operations, the radix
/// sort's key is a shift, and a position is decoded back to a float only where a plane's cost
/// is computed. Within a node the references are 0..N, so partition flags are a plain array
/// even when sibling subtrees are built in parallel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
#[repr(transparent)]
pub(super) struct Event(pub(super) u64);

impl Event {
    /// The event of `kind` at `pos` for the node's reference `reference`.
    pub(super) fn new(pos: f32, reference: usize, kind: u32) -> Self {
        // -0.0 + 0.0 = +0.0: both zeros sort and compare as one position.
        let bits = event_sort::ordered_bits(pos + 0.0) as u64;
        Self((bits << 32) | ((kind as u64) << REFERENCE_BITS) | reference as u64)
    }
    /// The position in `event_sort::ordered_bits` form: compares as the position does.
    #[inline]
    pub(super) fn pos_bits(self) -> u32 {
        (self.0 >> 32) as u32
    }
    #[cfg(test)]
    pub(super) fn pos(self) -> f32 {
        event_sort::position_of(self.pos_bits())
    }
    #[inline]
    pub(super) fn reference(self) -> usize {
        (self.0 & REFERENCE_MASK) as usize
    }
    #[cfg(test)]
    pub(super) fn kind(self) -> u32 {
        (self.0 >> REFERENCE_BITS) as u32 & 3
    }
    /// Position and kind: the sweep order.
    #[inline]
    pub(super) fn key(self) -> u64 {
        self.0 >> REFERENCE_BITS
    }
}

/// Sorts events in sweep order: a radix sort on the key for long lists (`event_sort`), an
/// integer sort for short ones (the fresh events of most splits). Lists are made in reference
/// order, and the radix sort is stable, so both give events equal in position and kind by
/// reference, an order the build does not depend on anyway (see `event_sort`).
pub(super) fn sort_events(list: &mut Vec<Event>, tmp: &mut Vec<Event>) {
    if list.len() >= event_sort::RADIX_MIN {
        event_sort::sort_by_key34(list, tmp, |e| e.key());
    } else {
        list.sort_unstable();
    }
}

/// Appends the events of `reference`'s box `b` to the three axes' lists, unsorted
/// (`sort_events` orders each list once all its events are in).
pub(super) fn push_events(events: &mut [Vec<Event>; 3], reference: usize, b: &Aabb) {
    for (k, list) in events.iter_mut().enumerate() {
        if b.lo[k] == b.hi[k] {
            list.push(Event::new(b.lo[k], reference, PLANAR));
        } else {
            list.push(Event::new(b.lo[k], reference, START));
            list.push(Event::new(b.hi[k], reference, END));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
