//! Counter-based sample values keyed by (pixel, sample, set, seed).
//!
//! Two samplers share one interface: independent uniforms, each a hash of its key (Jarzynski &
//! Olano, "Hash Functions for GPU Rendering", JCGT 2020, `pcg4d`), and shuffled Owen-scrambled
//! Sobol points (`sobol`, Burley 2020) whose per-pixel seeds come from the same hash. Nothing is
//! carried between samples or threads: the CPU and the GPU compute exactly the same value for
//! the same key, in any order, on any thread.

/// The `pcg4d` hash: 4 words in, 4 well-mixed words out, wrapping integer ops only.
#[inline]
pub fn pcg4d(a: u32, b: u32, c: u32, d: u32) -> [u32; 4] {
    let mut x = a.wrapping_mul(1664525).wrapping_add(1013904223);
    let mut y = b.wrapping_mul(1664525).wrapping_add(1013904223);
    let mut z = c.wrapping_mul(1664525).wrapping_add(1013904223);
    let mut w = d.wrapping_mul(1664525).wrapping_add(1013904223);
    x = x.wrapping_add(y.wrapping_mul(w));
    y = y.wrapping_add(z.wrapping_mul(x));
    z = z.wrapping_add(x.wrapping_mul(y));
    w = w.wrapping_add(y.wrapping_mul(z));
    x ^= x >> 16;
    y ^= y >> 16;
    z ^= z >> 16;
    w ^= w >> 16;
    x = x.wrapping_add(y.wrapping_mul(w));
    y = y.wrapping_add(z.wrapping_mul(x));
    z = z.wrapping_add(x.wrapping_mul(y));
    w = w.wrapping_add(y.wrapping_mul(z));
    [x, y, z, w]
}

/// Maps the top 24 bits to [0, 1): exact in f32, never 1.0.
#[inline]
pub fn u32_to_unit_f32(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// `RenderParams::sampler`: independent uniforms, each a hash of (pixel, sample, set, seed).
pub const SAMPLER_INDEPENDENT: u32 = 0;
/// `RenderParams::sampler`: shuffled Owen-scrambled Sobol points per set (`sobol`).
pub const SAMPLER_SOBOL: u32 = 1;

/// Keeps the Sobol seeds apart from the independent sampler's keys.
const SOBOL_KEY: u32 = 0x50b0_1b00;
/// Keys the hashes that a group of a pixel's samples shares (`Sampler::group_bits`) apart from
/// the samples' own.
pub const GROUP_KEY: u32 = 0x9e37_79b9;

/// Sets the Sobol sampler stratifies: the film position and the first two vertices' light and
/// BSDF sets. Deeper sets draw independent uniforms, at about a third of the cost: a Sobol set
/// is a chain of hashes and scrambles, and stratifying the third and later vertices bought
/// nothing measurable. Measured at 256×256, 64 spp, six seeds each against a 4096-spp
/// reference (BENCHMARKS.md): stratifying only the first vertex raised relMSE 2.1% (Cornell
/// box) and 2.5% (CornellBox-Sphere) for 9% and 5% less time; two vertices, 1.5% and 1.3% for
/// 6% and 4%; without the first BSDF set the error nearly doubles.
pub const SOBOL_SETS: u32 = 5;

/// Draws the uniforms of one sample of one pixel, one *set* of up to three dimensions at a time.
///
/// A path asks for its sets in a fixed order (the film position, then per vertex the light
/// sample and the BSDF sample with its roulette number), so set `k` means the same thing in
/// every sample: the Sobol sampler stratifies each set across a pixel's samples, and sets are
/// decorrelated by their own shuffles; sets from `SOBOL_SETS` on are independent uniforms. Both
/// samplers are pure functions of the key, so the CPU and the GPU draw the same numbers in any
/// order.
#[derive(Clone, Copy)]
pub struct Sampler {
    kind: u32,
    pixel: u32,
    sample: u32,
    seed: u32,
    set: u32,
    /// `sample.reverse_bits()`, shared by all of the sample's Sobol sets.
    reversed_sample: u32,
    /// On the CPU, the Sobol sets' seeds, which depend on the pixel and not on the sample:
    /// computed once for all of a pixel's samples (`PixelSeeds`), they were a third of the
    /// sampler's time. A GPU thread computes them per set instead of holding an array.
    #[cfg(not(target_arch = "spirv"))]
    seeds: PixelSeeds,
}

/// The Sobol sets' seeds of one pixel (`Sampler::sobol_seeds`) and each set's scrambled zero
/// (`sobol::shuffle_zero`), computed once for all of the pixel's samples (CPU only).
#[cfg(not(target_arch = "spirv"))]
#[derive(Clone, Copy)]
pub struct PixelSeeds {
    sets: [([u32; 4], u32); SOBOL_SETS as usize],
}

#[cfg(not(target_arch = "spirv"))]
impl PixelSeeds {
    /// The seeds of pixel `pixel` under sampler `kind`; the independent sampler reads none, so
    /// it gets zeros without the hashing.
    #[inline]
    pub fn new(kind: u32, pixel: u32, seed: u32) -> Self {
        let mut sets = [([0u32; 4], 0u32); SOBOL_SETS as usize];
        if kind != SAMPLER_SOBOL {
            return Self { sets };
        }
        for (set, s) in sets.iter_mut().enumerate() {
            let seeds = sobol_seeds(pixel, set as u32, seed);
            *s = (seeds, crate::sobol::shuffle_zero(seeds));
        }
        Self { sets }
    }

    /// Set `set`'s seeds and scrambled zero (the last set's for any later one): what
    /// `Sampler::next_2d` and `next_3d` use for it.
    #[inline(always)]
    pub fn of_set(&self, set: u32) -> ([u32; 4], u32) {
        self.sets[(set as usize).min(SOBOL_SETS as usize - 1)]
    }
}

/// Set `set`'s Sobol seeds: one shuffles the sample index, three scramble the coordinates
/// (`sobol::scrambled_sobol3`).
#[inline]
fn sobol_seeds(pixel: u32, set: u32, seed: u32) -> [u32; 4] {
    pcg4d(pixel, set, seed, SOBOL_KEY)
}

impl Sampler {
    #[inline]
    pub fn new(kind: u32, pixel: u32, sample: u32, seed: u32) -> Self {
        #[cfg(not(target_arch = "spirv"))]
        return Self::with_seeds(kind, pixel, sample, seed, PixelSeeds::new(kind, pixel, seed));
        #[cfg(target_arch = "spirv")]
        return Self { kind, pixel, sample, seed, set: 0, reversed_sample: sample.reverse_bits() };
    }

    /// `new` with the pixel's seeds computed beforehand (`PixelSeeds::new(kind, pixel, seed)`).
    #[cfg(not(target_arch = "spirv"))]
    #[inline]
    pub fn with_seeds(kind: u32, pixel: u32, sample: u32, seed: u32, seeds: PixelSeeds) -> Self {
        Self { kind, pixel, sample, seed, set: 0, reversed_sample: sample.reverse_bits(), seeds }
    }

    /// The three uniforms of an explicit set; `next_3d` walks the sets.
    #[inline]
    pub fn at(kind: u32, pixel: u32, sample: u32, set: u32, seed: u32) -> [f32; 3] {
        Self { set, ..Self::new(kind, pixel, sample, seed) }.next_3d()
    }

    /// The current set's Sobol seeds and scrambled zero (`sobol::shuffle_zero`); the set is
    /// below `SOBOL_SETS`.
    #[inline]
    fn sobol_seeds(&self) -> ([u32; 4], u32) {
        #[cfg(not(target_arch = "spirv"))]
        return self.seeds.of_set(self.set);
        #[cfg(target_arch = "spirv")]
        {
            let seeds = sobol_seeds(self.pixel, self.set, self.seed);
            (seeds, crate::sobol::shuffle_zero(seeds))
        }
    }

    /// The current set's independent uniforms, as bits.
    #[inline]
    fn independent_bits(&self) -> [u32; 4] {
        pcg4d(self.pixel, self.sample, self.set, self.seed)
    }

    #[inline(always)]
    pub fn next_3d(&mut self) -> [f32; 3] {
        let bits = if (self.kind == SAMPLER_SOBOL) & (self.set < SOBOL_SETS) {
            let (seeds, zero) = self.sobol_seeds();
            crate::sobol::scrambled_sobol3(self.reversed_sample, seeds, zero)
        } else {
            let h = self.independent_bits();
            [h[0], h[1], h[2]]
        };
        self.set += 1;
        [u32_to_unit_f32(bits[0]), u32_to_unit_f32(bits[1]), u32_to_unit_f32(bits[2])]
    }

    /// The first two dimensions of the next set (the most evenly spread pair under Sobol):
    /// exactly `next_3d`'s first two, without computing the third.
    #[inline(always)]
    pub fn next_2d(&mut self) -> (f32, f32) {
        let bits = if (self.kind == SAMPLER_SOBOL) & (self.set < SOBOL_SETS) {
            let (seeds, zero) = self.sobol_seeds();
            crate::sobol::scrambled_sobol2(self.reversed_sample, seeds, zero)
        } else {
            let h = self.independent_bits();
            [h[0], h[1]]
        };
        self.set += 1;
        (u32_to_unit_f32(bits[0]), u32_to_unit_f32(bits[1]))
    }

    /// A uniform independent of every set's, keyed by the last set drawn: the fourth word of the
    /// independent sampler's hash for that set (which its three uniforms leave unused). A BSDF
    /// picks its lobe with it: under the Sobol sampler a set's third dimension is stratified
    /// jointly with the direction's two, and a pick by it against a threshold biased the lobes'
    /// shares measurably (a plastic and a rough glass block against Mitsuba).
    #[inline]
    pub fn independent_after(&self) -> f32 {
        u32_to_unit_f32(pcg4d(self.pixel, self.sample, self.set.wrapping_sub(1), self.seed)[3])
    }

    /// Four uniforms of a hash keyed by `tag`, independent of every set (the light subpath's).
    #[inline]
    pub fn independent_4d(&self, tag: u32) -> [f32; 4] {
        let h = pcg4d(self.pixel, self.sample, tag, self.seed ^ 0x5bd1_e995);
        [u32_to_unit_f32(h[0]), u32_to_unit_f32(h[1]), u32_to_unit_f32(h[2]), u32_to_unit_f32(h[3])]
    }

    /// 32 bits of a hash keyed by `tag` that the pixel's samples `k * size .. (k + 1) * size`
    /// share (a pooled connection's window of candidates).
    #[inline]
    pub fn group_bits(&self, tag: u32, size: u32) -> u32 {
        pcg4d(self.pixel, self.sample / size, tag, self.seed ^ GROUP_KEY)[0]
    }

    /// The sample's index within its pixel.
    #[inline]
    pub fn sample(&self) -> u32 {
        self.sample
    }

    /// Sets drawn so far.
    #[inline]
    pub fn set(&self) -> u32 {
        self.set
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_interval_bounds() {
        assert_eq!(u32_to_unit_f32(0), 0.0);
        assert!(u32_to_unit_f32(u32::MAX) < 1.0);
    }

    #[test]
    fn keys_are_independent_and_reproducible() {
        for kind in [SAMPLER_INDEPENDENT, SAMPLER_SOBOL] {
            let mut s = Sampler::new(kind, 7, 3, 42);
            let a = s.next_3d();
            let b = s.next_3d();
            assert_ne!(a, b);
            assert_eq!(s.set(), 2);
            let mut t = Sampler::new(kind, 7, 3, 42);
            assert_eq!(t.next_2d(), (a[0], a[1]), "next_2d is next_3d's first two");
            assert_eq!(Sampler::at(kind, 7, 3, 0, 42), a);
            assert_eq!(Sampler::at(kind, 7, 3, 1, 42), b);
            assert_ne!(Sampler::at(kind, 7, 3, 0, 43), a);
            assert_ne!(Sampler::at(kind, 8, 3, 0, 42), a);
            assert_ne!(Sampler::at(kind, 7, 4, 0, 42), a);
        }
    }

    #[test]
    fn mean_and_variance_of_uniforms() {
        // 2^16 draws along each key axis and in each of the three dimensions: the mean of U(0,1)
        // is 1/2 ± 0.0011 (σ/√n ≈ 0.289/256) and the variance 1/12; 5σ bands keep false alarms
        // below 1e-6. Along the sample axis the Sobol points are stratified and land far closer.
        for kind in [SAMPLER_INDEPENDENT, SAMPLER_SOBOL] {
            for axis in 0..3 {
                let n = 1u32 << 16;
                let mut s1 = [0.0f64; 3];
                let mut s2 = [0.0f64; 3];
                for i in 0..n {
                    let v = match axis {
                        0 => Sampler::at(kind, i, 0, 0, 1),
                        1 => Sampler::at(kind, 0, i, 0, 1),
                        _ => Sampler::at(kind, 0, 0, i, 1),
                    };
                    for d in 0..3 {
                        s1[d] += v[d] as f64;
                        s2[d] += (v[d] as f64) * (v[d] as f64);
                    }
                }
                for d in 0..3 {
                    let mean = s1[d] / n as f64;
                    let var = s2[d] / n as f64 - mean * mean;
                    assert!((mean - 0.5).abs() < 5.0 * 0.2887 / 256.0, "kind {kind} axis {axis} dim {d} mean {mean}");
                    assert!((var - 1.0 / 12.0).abs() < 0.002, "kind {kind} axis {axis} dim {d} var {var}");
                }
            }
        }
    }

    #[test]
    fn sobol_sets_are_stratified_per_pixel_and_decorrelated_between_sets() {
        // 64 samples of one pixel: in every set, each of the 8×8 cells of dimensions (0, 1)
        // holds exactly one point (a (0,6,2)-net has one per 8×8 cell).
        // From `SOBOL_SETS` on the sets are independent uniforms: 64 of them leave some of the
        // 64 cells empty (all filled has probability 64!/64^64).
        for pixel in [0u32, 1, 12345] {
            for set in 0..SOBOL_SETS + 3 {
                let mut cells = [0u32; 64];
                for s in 0..64 {
                    let v = Sampler::at(SAMPLER_SOBOL, pixel, s, set, 9);
                    cells[((v[0] * 8.0) as usize) * 8 + (v[1] * 8.0) as usize] += 1;
                }
                let net = cells.iter().all(|&c| c == 1);
                assert_eq!(net, set < SOBOL_SETS, "pixel {pixel} set {set}: {cells:?}");
                if set >= SOBOL_SETS {
                    assert_eq!(
                        Sampler::at(SAMPLER_SOBOL, pixel, 7, set, 9),
                        Sampler::at(SAMPLER_INDEPENDENT, pixel, 7, set, 9)
                    );
                }
            }
        }
        // Different sets of one pixel are not the same sequence: the correlation of dimension 0
        // between two sets over 4096 samples is near 0 (|r| < 5/√4096 ≈ 0.08).
        let n = 4096;
        let (mut sa, mut sb, mut sab, mut saa, mut sbb) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
        for s in 0..n {
            let a = Sampler::at(SAMPLER_SOBOL, 3, s, 1, 9)[0] as f64;
            let b = Sampler::at(SAMPLER_SOBOL, 3, s, 2, 9)[0] as f64;
            sa += a;
            sb += b;
            sab += a * b;
            saa += a * a;
            sbb += b * b;
        }
        let nf = n as f64;
        let r =
            (sab / nf - sa / nf * sb / nf) / ((saa / nf - (sa / nf).powi(2)) * (sbb / nf - (sb / nf).powi(2))).sqrt();
        assert!(r.abs() < 5.0 / nf.sqrt(), "sets correlated: r = {r}");
    }
}
