//! `rng::Sampler` for sixteen samples: lane i draws what `Sampler` draws for its pixel and
//! sample, set by set. Paths in lockstep draw the same set at the same time, so only the pixel
//! (its Sobol sets' seeds, `PixelSeeds`, one row per set) and the sample index differ between
//! lanes: the scrambles, the Sobol matrices and the hashes are integer operations on sixteen
//! lanes at once.
use super::{F, U};
use crate::rng::{PixelSeeds, GROUP_KEY, SAMPLER_SOBOL, SOBOL_SETS};
use core::simd::cmp::SimdPartialEq;
use core::simd::num::SimdUint;
use core::simd::Select;

/// `sobol::laine_karras`, lane by lane, each lane with its own seed.
#[inline(always)]
fn laine_karras(x: U, seed: U) -> U {
    let mut x = x + seed;
    x ^= x * U::splat(0x6c50_b47c);
    x ^= x * U::splat(0xb82f_1e52);
    x ^= x * U::splat(0xc7af_e638);
    x ^= x * U::splat(0x8d22_f6e6);
    x
}

/// `sobol::superset_sum`, lane by lane.
#[inline(always)]
fn superset_sum(s: U) -> U {
    let mut y = s;
    y ^= (y >> 1) & U::splat(0x5555_5555);
    y ^= (y >> 2) & U::splat(0x3333_3333);
    y ^= (y >> 4) & U::splat(0x0f0f_0f0f);
    y ^= (y >> 8) & U::splat(0x00ff_00ff);
    y ^= (y >> 16) & U::splat(0x0000_ffff);
    y
}

/// `rng::pcg4d`, lane by lane (the vector operations wrap, as its `wrapping_` ones).
#[inline(always)]
pub fn pcg4d(a: U, b: U, c: U, d: U) -> [U; 4] {
    let (m, k) = (U::splat(1664525), U::splat(1013904223));
    let (mut x, mut y, mut z, mut w) = (a * m + k, b * m + k, c * m + k, d * m + k);
    x += y * w;
    y += z * x;
    z += x * y;
    w += y * z;
    x ^= x >> 16;
    y ^= y >> 16;
    z ^= z >> 16;
    w ^= w >> 16;
    x += y * w;
    y += z * x;
    z += x * y;
    w += y * z;
    [x, y, z, w]
}

/// `rng::u32_to_unit_f32`, lane by lane.
#[inline(always)]
pub fn unit(x: U) -> F {
    (x >> 8).cast::<f32>() * F::splat(1.0 / 16_777_216.0)
}

/// `sobol::scrambled_sobol2` and the third coordinate of `scrambled_sobol3` when `three`.
#[inline(always)]
fn scrambled_sobol(reversed: U, seeds: &([U; 4], U), three: bool) -> [U; 3] {
    let (s, zero) = seeds;
    let shuffled = laine_karras(reversed, s[0]) ^ *zero;
    // `sobol2_reversed`: dimension 0 is the index itself, dimension 1 its superset sums.
    let x0 = shuffled.reverse_bits();
    let x1 = superset_sum(x0);
    let mut x2 = U::splat(0);
    if three {
        // `sobol3_reversed`'s loop over the index's bits, top first, until every lane's
        // remaining bits are zero (a lane whose bits ran out adds nothing).
        let (mut w2, mut w2_next, mut r) = (U::splat(1), U::splat(3), shuffled);
        let top = U::splat(0x8000_0000);
        while r.simd_ne(U::splat(0)).any() {
            x2 = (r & top).simd_ne(U::splat(0)).select(x2 ^ w2, x2);
            r <<= 1;
            let w2_after = w2_next ^ w2 ^ (w2 << 2);
            w2 = w2_next;
            w2_next = w2_after;
        }
    }
    [
        laine_karras(x0, s[1]).reverse_bits(),
        laine_karras(x1, s[2]).reverse_bits(),
        if three { laine_karras(x2, s[3]).reverse_bits() } else { U::splat(0) },
    ]
}

/// The Sobol sets' seeds and scrambled zeros of each lane's pixel (`PixelSeeds`), as rows: set
/// `s`'s four seeds and zero for the sixteen lanes.
#[derive(Clone, Copy)]
pub struct LaneSeeds {
    sets: [([U; 4], U); SOBOL_SETS as usize],
}

impl LaneSeeds {
    /// Every lane with the seeds of one pixel.
    #[inline(always)]
    pub fn splat(seeds: &PixelSeeds) -> Self {
        let mut lanes = Self { sets: [([U::splat(0); 4], U::splat(0)); SOBOL_SETS as usize] };
        for set in 0..SOBOL_SETS {
            let (s, zero) = seeds.of_set(set);
            lanes.sets[set as usize] = (s.map(U::splat), U::splat(zero));
        }
        lanes
    }

    /// Lane `lane` takes the seeds of its pixel, `seeds`.
    #[inline(always)]
    pub fn set_lane(&mut self, lane: usize, seeds: &PixelSeeds) {
        for set in 0..SOBOL_SETS {
            let (s, zero) = seeds.of_set(set);
            let row = &mut self.sets[set as usize];
            for (r, v) in row.0.iter_mut().zip(s) {
                r[lane] = v;
            }
            row.1[lane] = zero;
        }
    }

    /// Set `set`'s rows (the last set's for any later one), as `PixelSeeds::of_set`.
    #[inline(always)]
    fn of_set(&self, set: u32) -> &([U; 4], U) {
        &self.sets[(set as usize).min(SOBOL_SETS as usize - 1)]
    }
}

/// The sampler of sixteen samples: lane i is `Sampler::new(kind, pixel[i], sample[i], seed)`.
#[derive(Clone, Copy)]
pub struct LaneSampler {
    kind: u32,
    pixel: U,
    seed: u32,
    set: u32,
    sample: U,
    reversed: U,
    seeds: LaneSeeds,
}

impl LaneSampler {
    /// The samples `sample` of pixels `pixel` (lane by lane), whose seeds are `seeds` (lane i
    /// holding `PixelSeeds::new(kind, pixel[i], seed)`).
    #[inline(always)]
    pub fn new(kind: u32, pixel: U, sample: U, seed: u32, seeds: LaneSeeds) -> Self {
        Self { kind, pixel, seed, set: 0, sample, reversed: sample.reverse_bits(), seeds }
    }

    #[inline(always)]
    fn bits(&mut self, three: bool) -> [U; 3] {
        let bits = if (self.kind == SAMPLER_SOBOL) & (self.set < SOBOL_SETS) {
            scrambled_sobol(self.reversed, self.seeds.of_set(self.set), three)
        } else {
            let h = pcg4d(self.pixel, self.sample, U::splat(self.set), U::splat(self.seed));
            [h[0], h[1], h[2]]
        };
        self.set += 1;
        bits
    }

    /// `Sampler::next_3d`.
    #[inline(always)]
    pub fn next_3d(&mut self) -> [F; 3] {
        let b = self.bits(true);
        [unit(b[0]), unit(b[1]), unit(b[2])]
    }

    /// `Sampler::next_2d`.
    #[inline(always)]
    pub fn next_2d(&mut self) -> (F, F) {
        let b = self.bits(false);
        (unit(b[0]), unit(b[1]))
    }

    /// `Sampler::group_bits`, lane by lane.
    #[inline(always)]
    pub fn group_bits(&self, tag: u32, size: u32) -> U {
        pcg4d(self.pixel, self.sample / U::splat(size), U::splat(tag), U::splat(self.seed ^ GROUP_KEY))[0]
    }

    /// The lanes' sample indices.
    #[inline(always)]
    pub fn sample(&self) -> U {
        self.sample
    }

    /// The lanes' pixels.
    #[inline(always)]
    pub fn pixel(&self) -> U {
        self.pixel
    }

    /// Four uniforms of a hash keyed by `tag`, independent of every set.
    #[inline(always)]
    pub fn independent_4d(&self, tag: u32) -> [F; 4] {
        let h = pcg4d(self.pixel, self.sample, U::splat(tag), U::splat(self.seed ^ 0x5bd1_e995));
        [unit(h[0]), unit(h[1]), unit(h[2]), unit(h[3])]
    }

    /// `Sampler::independent_after`: a uniform independent of the last set, for a BSDF's lobe
    /// pick.
    #[inline(always)]
    pub fn independent_after(&self) -> F {
        let set = U::splat(self.set.wrapping_sub(1));
        unit(pcg4d(self.pixel, self.sample, set, U::splat(self.seed))[3])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{pcg4d as pcg4d_scalar, Sampler, SAMPLER_INDEPENDENT};

    /// Each lane draws its own pixel's and sample's numbers: lanes of one pixel (its seeds
    /// splatted) and lanes of several pixels (set lane by lane), as a group of a pass of few
    /// samples holds.
    #[test]
    fn lanes_draw_what_the_scalar_sampler_draws() {
        for kind in [SAMPLER_SOBOL, SAMPLER_INDEPENDENT] {
            for (pixel, seed, first, spread) in [
                (0u32, 0u32, 0u32, 0u32),
                (77, 3, 16, 0),
                (65_535, 0xdead, 1_000_003, 0),
                (5, 1, u32::MAX - 15, 0),
                (9, 4, 0, 1),
                (1_000, 17, 40, 3),
            ] {
                let samples = U::from_array(core::array::from_fn(|i| first.wrapping_add(i as u32 * 7)));
                let pixels = U::from_array(core::array::from_fn(|i| pixel + spread * (i as u32 / 3)));
                let mut seeds = LaneSeeds::splat(&PixelSeeds::new(kind, pixel, seed));
                if spread != 0 {
                    for i in 0..16 {
                        seeds.set_lane(i, &PixelSeeds::new(kind, pixels[i], seed));
                    }
                }
                let mut lanes = LaneSampler::new(kind, pixels, samples, seed, seeds);
                assert_eq!(lanes.pixel(), pixels);
                let mut scalar: [Sampler; 16] =
                    core::array::from_fn(|i| Sampler::new(kind, pixels[i], samples[i], seed));
                let (group, light) = (lanes.group_bits(11, 16), lanes.independent_4d(5));
                for (i, s) in scalar.iter().enumerate() {
                    assert_eq!(group[i], s.group_bits(11, 16), "{kind} {pixel} {i}");
                    let l = s.independent_4d(5);
                    assert_eq!(light.map(|f| f[i].to_bits()), l.map(f32::to_bits), "{kind} {pixel} {i}");
                }
                for set in 0..(SOBOL_SETS + 3) {
                    if set % 2 == 0 {
                        let (a, b) = lanes.next_2d();
                        for (i, s) in scalar.iter_mut().enumerate() {
                            let (x, y) = s.next_2d();
                            assert_eq!(
                                (a[i].to_bits(), b[i].to_bits()),
                                (x.to_bits(), y.to_bits()),
                                "{kind} {pixel} {set} {i}"
                            );
                        }
                    } else {
                        let l = lanes.next_3d();
                        for (i, s) in scalar.iter_mut().enumerate() {
                            let x = s.next_3d();
                            for d in 0..3 {
                                assert_eq!(l[d][i].to_bits(), x[d].to_bits(), "{kind} {pixel} {set} {i} {d}");
                            }
                        }
                    }
                    let pick = lanes.independent_after();
                    for (i, s) in scalar.iter().enumerate() {
                        assert_eq!(pick[i].to_bits(), s.independent_after().to_bits(), "{kind} {pixel} {set} {i}");
                    }
                }
            }
        }
    }

    #[test]
    fn hash_matches_lane_by_lane() {
        let a = U::from_array(core::array::from_fn(|i| (i as u32).wrapping_mul(0x9e37_79b9)));
        let h = pcg4d(a, a ^ U::splat(5), U::splat(7), a >> 3);
        for i in 0..16 {
            assert_eq!([h[0][i], h[1][i], h[2][i], h[3][i]], pcg4d_scalar(a[i], a[i] ^ 5, 7, a[i] >> 3));
        }
    }
}
