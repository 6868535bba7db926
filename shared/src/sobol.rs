//! Owen-scrambled, shuffled Sobol points: Burley, "Practical Hash-based Owen Scrambling",
//! JCGT 9(4), 2020 (the "Sobol-Burley" sampler of Cycles).
//!
//! - The first three Sobol dimensions come from their primitive polynomials and initial
//!   direction numbers (Joe & Kuo, "Constructing Sobol sequences with better two-dimensional
//!   projections", SIAM J. Sci. Comput. 2008: dimension 0 is van der Corput, then
//!   (s, a, m) = (1, 0, {1}) and (2, 1, {1, 3})), generated bit by bit from the recurrence: no
//!   table, so the GPU needs no constant arrays; the loop runs once per bit of the sample index.
//! - Each coordinate is Owen-scrambled (a nested uniform scramble: a digit flips depending only on
//!   the digits above it) by a hash on the bit-reversed value, as Laine & Karras ("Stratified
//!   sampling for stochastic transparency", EGSR 2011) built it, with Burley's constants.
//! - The sample index is scrambled the same way before the point is made. Every set of dimensions
//!   has its own seeds, so sets walk independent orders of the sequence (padding, Kollig &
//!   Keller 2002) while each pixel's first 2^m indices still map to one aligned block of 2^m
//!   Sobol points: a (0, m, 2)-net in dimensions 0 and 1 of every set.
//!
//! Owen scrambling makes every point uniformly distributed, so estimates stay unbiased; the
//! per-pixel seeds keep pixels' errors independent. Integer operations only: the CPU and any GPU
//! compute the same bits.

/// A permutation of u32 in which output bit k depends only on input bits 0..=k (addition and
/// multiplication by even constants carry only upwards): applied to bit-reversed values it is a
/// nested uniform (Owen) scramble. Constants from Burley 2020, §3.
#[inline]
fn laine_karras(x: u32, seed: u32) -> u32 {
    let mut x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x
}

/// Owen-scrambles `x` read as a binary fraction (bit 31 the first digit).
#[inline]
pub fn nested_uniform_scramble(x: u32, seed: u32) -> u32 {
    // `reverse_bits` is one instruction on GPUs (SPIR-V OpBitReverse).
    laine_karras(x.reverse_bits(), seed).reverse_bits()
}

/// Owen-scrambles the sample index with 0 kept at 0, so every index below 2^m stays below 2^m.
///
/// Output bit b of a nested scramble depends only on input bits b and above, so all indices
/// below 2^m share the scrambled high bits of 0; xoring them away keeps a permutation of each
/// aligned block (still a nested scramble: a digital shift of one) and lets `sobol3` walk only
/// the sample index's own bits instead of all 32. The points lose nothing: by linearity the
/// dropped high bits would only xor a constant into every point, which the coordinates' own
/// Owen scrambles absorb.
#[inline]
pub fn shuffle_index(index: u32, seed: u32) -> u32 {
    nested_uniform_scramble(index, seed) ^ nested_uniform_scramble(0, seed)
}

/// Point `index` of the unscrambled Sobol sequence in dimensions 0, 1 and 2, as 32-bit fractions.
///
/// Walks the index's bits; the direction numbers v_k of each dimension follow its recurrence
/// v_{k+s} = a_1 v_{k+s-1} ⊕ … ⊕ v_k ⊕ (v_k >> s). The loop runs once per significant bit of
/// `index` (at most 32), so small sample counts cost a few steps.
#[inline]
pub fn sobol3(index: u32) -> [u32; 3] {
    let (mut x0, mut x1, mut x2) = (0u32, 0u32, 0u32);
    // Dimension 0: v_k = 2^(32-k).
    let mut v0 = 1u32 << 31;
    // Dimension 1, s = 1: v_{k+1} = v_k ⊕ (v_k >> 1), m_1 = 1.
    let mut v1 = 1u32 << 31;
    // Dimension 2, s = 2, a = 1: v_{k+2} = v_{k+1} ⊕ v_k ⊕ (v_k >> 2), m = 1, 3.
    let mut v2 = 1u32 << 31;
    let mut v2_next = 3u32 << 30;
    let mut i = index;
    while i != 0 {
        if (i & 1) != 0 {
            x0 ^= v0;
            x1 ^= v1;
            x2 ^= v2;
        }
        i >>= 1;
        v0 >>= 1;
        v1 ^= v1 >> 1;
        let v2_after = v2_next ^ v2 ^ (v2 >> 2);
        v2 = v2_next;
        v2_next = v2_after;
    }
    [x0, x1, x2]
}

/// Dimensions 0 and 1 of `sobol3_reversed`, for sets that need only two, without a loop over
/// the index bits. With s = the index (`reversed_index` reversed back), dimension 0 in the
/// reversed domain is s itself, and dimension 1 is s through the Pascal matrix mod 2: bit j
/// gathers bit k of s for every k whose bits include j's (Lucas: C(k, j) is odd iff j ⊆ k), a
/// sum over supersets that five shift-and-mask steps compute (the fast zeta transform).
#[inline]
pub fn sobol2_reversed(reversed_index: u32) -> [u32; 2] {
    let s = reversed_index.reverse_bits();
    [s, superset_sum(s)]
}

/// Bit j of the result is the XOR of the bits k of `s` with j ⊆ k (k's bits include j's).
#[inline]
fn superset_sum(s: u32) -> u32 {
    let mut y = s;
    y ^= (y >> 1) & 0x5555_5555;
    y ^= (y >> 2) & 0x3333_3333;
    y ^= (y >> 4) & 0x0f0f_0f0f;
    y ^= (y >> 8) & 0x00ff_00ff;
    y ^= (y >> 16) & 0x0000_ffff;
    y
}

/// The index shuffle's image of 0 under `seeds` (`shuffle_index` xors it away): the same for
/// every sample of a set, so a sampler may compute it once.
#[inline]
pub fn shuffle_zero(seeds: [u32; 4]) -> u32 {
    laine_karras(0, seeds[0])
}

/// `scrambled_sobol3`'s first two coordinates at two thirds of the work; `zero` is
/// `shuffle_zero(seeds)`.
#[inline]
pub fn scrambled_sobol2(reversed_index: u32, seeds: [u32; 4], zero: u32) -> [u32; 2] {
    let shuffled = laine_karras(reversed_index, seeds[0]) ^ zero;
    let x = sobol2_reversed(shuffled);
    [laine_karras(x[0], seeds[1]).reverse_bits(), laine_karras(x[1], seeds[2]).reverse_bits()]
}

/// `sobol3` in the bit-reversed domain: takes the reversed index and returns the reversed
/// coordinates, with the direction numbers' recurrences mirrored (left shifts). The scrambles
/// work on reversed values, so this saves a reversal per coordinate and one of the index.
#[inline]
pub fn sobol3_reversed(reversed_index: u32) -> [u32; 3] {
    let [x0, x1] = sobol2_reversed(reversed_index);
    let mut x2 = 0u32;
    let mut w2 = 1u32;
    let mut w2_next = 3u32;
    let mut r = reversed_index;
    while r != 0 {
        if (r & 0x8000_0000) != 0 {
            x2 ^= w2;
        }
        r <<= 1;
        let w2_after = w2_next ^ w2 ^ (w2 << 2);
        w2 = w2_next;
        w2_next = w2_after;
    }
    [x0, x1, x2]
}

/// Point `index` of the shuffled, Owen-scrambled Sobol sequence in three dimensions, as 32-bit
/// fractions: `nested_uniform_scramble(sobol3(shuffle_index(index, seeds[0]))[d], seeds[d + 1])`,
/// computed in the reversed domain. `reversed_index` is `index.reverse_bits()`, which a
/// sampler computes once per sample for all its sets; `zero` is `shuffle_zero(seeds)`.
#[inline]
pub fn scrambled_sobol3(reversed_index: u32, seeds: [u32; 4], zero: u32) -> [u32; 3] {
    let shuffled = laine_karras(reversed_index, seeds[0]) ^ zero;
    let x = sobol3_reversed(shuffled);
    [
        laine_karras(x[0], seeds[1]).reverse_bits(),
        laine_karras(x[1], seeds[2]).reverse_bits(),
        laine_karras(x[2], seeds[3]).reverse_bits(),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Direction numbers v_1..v_5 of dimensions 1 and 2 as published in Joe & Kuo's
    /// `new-joe-kuo-6.21201` (in pbrt-v4's `SobolMatrices32`, top bytes), and van der Corput.
    #[test]
    #[allow(clippy::needless_range_loop)]
    fn direction_numbers_match_the_published_matrices() {
        let published: [[u32; 5]; 3] =
            [[0x80, 0x40, 0x20, 0x10, 0x08], [0x80, 0xc0, 0xa0, 0xf0, 0x88], [0x80, 0xc0, 0x60, 0x90, 0xe8]];
        for k in 0..5 {
            let x = sobol3(1 << k);
            for d in 0..3 {
                assert_eq!(x[d], published[d][k] << 24, "dimension {d}, v_{}", k + 1);
            }
        }
        // Linearity over GF(2): the point of a sum of bits is the xor of the points.
        let (a, b) = (0b1011_0110u32, 0b0100_1001u32);
        let (xa, xb, xab) = (sobol3(a), sobol3(b), sobol3(a | b));
        for d in 0..3 {
            assert_eq!(xa[d] ^ xb[d], xab[d]);
        }
    }

    /// The loop-free dimensions 0 and 1 against the direction-number loop, on random 32-bit
    /// indices (the other tests cover small ones).
    #[test]
    fn closed_forms_equal_the_loop() {
        let mut x = 0x1234_5678u32;
        for _ in 0..20_000 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            let (mut x0, mut x1, mut w0, mut w1, mut r) = (0u32, 0u32, 1u32, 1u32, x);
            while r != 0 {
                if (r & 0x8000_0000) != 0 {
                    x0 ^= w0;
                    x1 ^= w1;
                }
                r <<= 1;
                w0 <<= 1;
                w1 ^= w1 << 1;
            }
            assert_eq!(sobol2_reversed(x), [x0, x1], "reversed index {x:#x}");
        }
    }

    #[test]
    fn reversed_domain_equals_the_definition() {
        let seeds = [0x0123_4567, 0x89ab_cdef, 0xdead_beef, 0x0bad_f00d];
        for i in (0..5000u32).chain([u32::MAX, 1 << 31, 0x5555_5555]) {
            let x = sobol3(i);
            let r = sobol3_reversed(i.reverse_bits());
            for d in 0..3 {
                assert_eq!(r[d], x[d].reverse_bits(), "index {i} dimension {d}");
            }
            let shuffled = sobol3(shuffle_index(i, seeds[0]));
            let fast = scrambled_sobol3(i.reverse_bits(), seeds, shuffle_zero(seeds));
            let two = scrambled_sobol2(i.reverse_bits(), seeds, shuffle_zero(seeds));
            assert_eq!([fast[0], fast[1]], two, "index {i}");
            for d in 0..3 {
                assert_eq!(fast[d], nested_uniform_scramble(shuffled[d], seeds[d + 1]), "index {i} dimension {d}");
            }
        }
    }

    #[test]
    fn shuffled_blocks_stay_blocks() {
        for seed in [0u32, 1, 0xdead_beef, 0x8000_0001] {
            for m in [0u32, 1, 5, 10] {
                let mut seen = vec![false; 1 << m];
                for i in 0..1u32 << m {
                    let j = shuffle_index(i, seed);
                    assert!(j < 1 << m, "seed {seed}: {i} -> {j} leaves the block of 2^{m}");
                    assert!(!seen[j as usize]);
                    seen[j as usize] = true;
                }
            }
        }
    }

    /// Counts, for a 2D point set of 2^m points, whether every elementary interval of area
    /// 2^-m (all 2^a × 2^(m-a) grids) holds exactly one point.
    fn is_0m2_net(points: &[(u32, u32)], m: u32) -> bool {
        for a in 0..=m {
            let b = m - a;
            let mut counts = vec![0u32; 1 << m];
            for &(x, y) in points {
                let cx = if a == 0 { 0 } else { x >> (32 - a) };
                let cy = if b == 0 { 0 } else { y >> (32 - b) };
                counts[((cx << b) | cy) as usize] += 1;
            }
            if counts.iter().any(|&c| c != 1) {
                return false;
            }
        }
        true
    }

    #[test]
    fn every_scrambled_shuffled_prefix_is_a_0m2_net() {
        for seed in 0..20u32 {
            let seeds = [seed.wrapping_mul(0x9e37_79b9), seed ^ 0x51ed_270b, seed.wrapping_add(77), !seed];
            for m in 0..=8 {
                let pts: Vec<(u32, u32)> = (0..1u32 << m)
                    .map(|i| {
                        let p = scrambled_sobol3(i.reverse_bits(), seeds, shuffle_zero(seeds));
                        (p[0], p[1])
                    })
                    .collect();
                assert!(is_0m2_net(&pts, m), "seed {seed}, 2^{m} points");
                // Each coordinate alone is stratified into 2^m equal intervals, dimension 2 included.
                for d in 0..3 {
                    let mut cells = vec![0u32; 1 << m];
                    for i in 0..1u32 << m {
                        let v = scrambled_sobol3(i.reverse_bits(), seeds, shuffle_zero(seeds))[d];
                        cells[if m == 0 { 0 } else { (v >> (32 - m)) as usize }] += 1;
                    }
                    assert!(cells.iter().all(|&c| c == 1), "seed {seed}, dimension {d}, 2^{m} points");
                }
            }
        }
    }

    #[test]
    fn unscrambled_points_are_not_a_net_after_a_wrong_direction_number() {
        // The net test can fail: dimension 1 with v_2 flipped is no longer a (0, m, 2)-net.
        let pts: Vec<(u32, u32)> = (0..16u32)
            .map(|i| {
                let x = sobol3(i);
                (x[0], if i & 2 != 0 { x[1] ^ (0xc0 << 24) ^ (0x40 << 24) } else { x[1] })
            })
            .collect();
        assert!(!is_0m2_net(&pts, 4));
        let good: Vec<(u32, u32)> = (0..16u32).map(|i| (sobol3(i)[0], sobol3(i)[1])).collect();
        assert!(is_0m2_net(&good, 4));
    }

    #[test]
    fn scramble_is_a_nested_permutation() {
        // Digit k of the output depends only on digits 1..=k of the input: the top 8 bits of
        // the scrambled value are a function of the top 8 input bits, and a bijection on them.
        let seed = 0x1234_abcd;
        let mut seen = [false; 256];
        for top in 0..256u32 {
            let a = nested_uniform_scramble(top << 24, seed) >> 24;
            let b = nested_uniform_scramble((top << 24) | 0x00ab_cdef, seed) >> 24;
            assert_eq!(a, b, "top bits leak from below");
            assert!(!seen[a as usize], "not a bijection");
            seen[a as usize] = true;
        }
    }
}
