//! Sorting the SAH builder's events by (position, kind) with an LSD radix sort.
//!
//! Wald & Havran's builder sorts every axis's events once at the root (§5.3) and the fresh
//! events of straddling triangles at each split. A comparison sort spent about 500 instructions
//! per root event (a quarter of a mesh's build); a radix sort on the 34-bit key — the position's
//! bits mapped to an unsigned integer of the same order (IEEE total order, as `f32::total_cmp`)
//! above the 2-bit kind — takes three counting passes. Events equal in both keep their input
//! order (the sort is stable), which no caller relies on: the sweep counts runs of equal
//! positions and the partition reads codes by reference.

/// Lists shorter than this are better sorted otherwise (the builder sorts its events as integers,
/// `sah::event::sort_events`): three passes over 2048-entry histograms cost more than sorting a
/// few hundred events directly.
pub const RADIX_MIN: usize = 512;

/// Bits of the key per pass: 11 + 11 + 12 = 34.
const PASSES: [(u32, u32); 3] = [(0, 11), (11, 11), (22, 12)];

/// The f32's bits as an unsigned integer whose order is `f32::total_cmp`'s.
#[inline]
pub fn ordered_bits(x: f32) -> u32 {
    let b = x.to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// The position whose `ordered_bits` are `u`.
#[inline]
pub fn position_of(u: u32) -> f32 {
    f32::from_bits(if u & 0x8000_0000 != 0 { u & 0x7fff_ffff } else { !u })
}

/// The sort key of a position and a 2-bit kind: by position, then kind.
#[cfg(test)]
fn key(pos: f32, kind: u32) -> u64 {
    ((ordered_bits(pos) as u64) << 2) | (kind & 3) as u64
}

/// Sorts `items` by `key_of` (34-bit keys, as from `key`), stably; `tmp` is scratch space kept
/// by the caller between calls. Correct for any length, worth it from `RADIX_MIN` on. The key
/// is recomputed in every pass rather than stored: the builder's events carry theirs in their
/// top bits, so a shift is cheaper than a second array to scatter.
pub fn sort_by_key34<T: Copy>(items: &mut Vec<T>, tmp: &mut Vec<T>, key_of: impl Fn(&T) -> u64) {
    let n = items.len();
    // All three histograms in one pass over the items.
    let mut counts = vec![0usize; 3 << 12];
    for item in items.iter() {
        let k = key_of(item);
        for (p, (shift, bits)) in PASSES.into_iter().enumerate() {
            counts[(p << 12) + ((k >> shift) & ((1u64 << bits) - 1)) as usize] += 1;
        }
    }
    tmp.clear();
    tmp.reserve(n);
    for (p, (shift, bits)) in PASSES.into_iter().enumerate() {
        let mask = (1u64 << bits) - 1;
        let counts = &mut counts[p << 12..(p << 12) + (1 << bits)];
        // A pass whose digit is the same for every key would move nothing.
        if counts.contains(&n) {
            continue;
        }
        let mut sum = 0;
        for c in counts.iter_mut() {
            let here = *c;
            *c = sum;
            sum += here;
        }
        tmp.clear();
        {
            let out = &mut tmp.spare_capacity_mut()[..n];
            for item in items.iter() {
                let slot = &mut counts[((key_of(item) >> shift) & mask) as usize];
                out[*slot].write(*item);
                *slot += 1;
            }
        }
        // SAFETY: the prefix sums give every item its own slot below n, so the scatter wrote
        // all n slots of `tmp`, which was empty.
        unsafe {
            tmp.set_len(n);
        }
        std::mem::swap(items, tmp);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ordered_bits_follow_total_order() {
        let xs = [
            f32::NEG_INFINITY,
            -1e30,
            -2.0,
            -1.0,
            -f32::MIN_POSITIVE,
            -1e-45,
            -0.0,
            0.0,
            1e-45,
            f32::MIN_POSITIVE,
            0.5,
            1.0,
            3.0e38,
            f32::INFINITY,
        ];
        for w in xs.windows(2) {
            assert!(ordered_bits(w[0]) < ordered_bits(w[1]), "{} !< {}", w[0], w[1]);
            assert_eq!(w[0].total_cmp(&w[1]), ordered_bits(w[0]).cmp(&ordered_bits(w[1])));
        }
        for x in xs {
            assert_eq!(position_of(ordered_bits(x)).to_bits(), x.to_bits(), "{x}");
        }
    }

    /// Against a stable comparison sort on random lists with many ties (few distinct
    /// positions, all kinds, both signs, zeros), short and long.
    #[test]
    fn radix_sort_equals_a_stable_comparison_sort() {
        let mut next = crate::kdbuild::xorshift(0x9e37_79b9_7f4a_7c15);
        let palette = [-3.5f32, -1.0, -0.0, 0.0, 1e-40, 0.25, 1.0, 7.0, 1e20];
        let mut tmp = Vec::new();
        for n in [0usize, 1, 5, RADIX_MIN - 1, RADIX_MIN, 3000, 20_000] {
            for distinct in [2usize, 9, 0] {
                let items: Vec<(f32, u32, usize)> = (0..n)
                    .map(|i| {
                        let r = next();
                        let pos = if distinct == 0 {
                            f32::from_bits((r >> 32) as u32 & 0x7f7f_ffff) * if r & 1 == 0 { 1.0 } else { -1.0 }
                        } else {
                            palette[(r as usize >> 8) % distinct.min(palette.len())]
                        };
                        (pos, (r >> 4) as u32 % 3, i)
                    })
                    .collect();
                let cmp = |a: &(f32, u32, usize), b: &(f32, u32, usize)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
                let mut want = items.clone();
                want.sort_by(|a, b| cmp(a, b));
                let mut got = items.clone();
                sort_by_key34(&mut got, &mut tmp, |e| key(e.0, e.1));
                // Stable: ties keep their input order, exactly the stable sort's output.
                assert_eq!(
                    got.iter().map(|e| e.2).collect::<Vec<_>>(),
                    want.iter().map(|e| e.2).collect::<Vec<_>>(),
                    "n {n} distinct {distinct}"
                );
                let mut keys: Vec<_> = got.iter().map(|e| (e.0.to_bits(), e.1)).collect();
                let mut wk: Vec<_> = want.iter().map(|e| (e.0.to_bits(), e.1)).collect();
                keys.sort();
                wk.sort();
                assert_eq!(keys, wk, "the same items");
            }
        }
    }
}
