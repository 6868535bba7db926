//! The sweep's event groups (`Sah::sweep`): `LANES` events at a time turned into bit masks of
//! where runs of one position end and which events are ends and planars (`run_masks`), and the
//! counts of kinds in a block of events (`kind_counts`). Wald & Havran 2006 ("On building fast
//! kd-Trees for Ray Tracing, and on doing that in O(N log N)", §5.1) walk the sorted events one
//! at a time and price a plane at each run's end; with the masks the sweep reaches the run ends
//! by bit operations, and passes over whole groups and blocks whose least possible cost is too
//! high without visiting their runs.
use super::event::{END, PLANAR, REFERENCE_BITS};
use std::simd::prelude::*;

/// Events a sweep takes at once (`run_masks`).
pub(super) const LANES: usize = 16;

/// Where runs of events at one position end among the `LANES` events from `first`, and which of
/// them are ends and which planars, as bit masks (bit l for `events[first + l]`; past the
/// list's end, nothing). The events are compared with their successors at once
/// (`core::simd`), with no dependence on where the previous run ended: on a mesh a run is a
/// vertex shared by a few triangles, one to eight events of no predictable count, and a loop that
/// stopped at each run's end mispredicted that stop at nearly every run.
#[inline]
pub(super) fn run_masks(raw: &[u64], first: usize) -> Group {
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

/// `LANES` events of a sweep (`run_masks`): bit l of each mask is about the l-th.
pub(super) struct Group {
    /// Events that end their run (the last of their position).
    pub(super) runs: u32,
    pub(super) ends: u32,
    pub(super) planar: u32,
    /// Positions (`Event::pos_bits`).
    pub(super) bits: [u32; LANES],
}

/// The starts and the planars among `events` (a multiple of eight long): what the sweep's
/// block screen needs of a block it may pass over.
#[inline]
pub(super) fn kind_counts(events: &[u64]) -> (usize, usize) {
    type Lanes = Simd<u64, 8>;
    let (mut starts, mut planars) = (Lanes::splat(0), Lanes::splat(0));
    for chunk in events.as_chunks::<8>().0 {
        let kind = (Lanes::from_array(*chunk) >> REFERENCE_BITS as u64) & Lanes::splat(3);
        starts += kind >> 1;
        planars += kind & Lanes::splat(1);
    }
    debug_assert!(events.len().is_multiple_of(8));
    (starts.reduce_sum() as usize, planars.reduce_sum() as usize)
}
