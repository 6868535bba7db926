//! The CPU reference renderer: rayon over rows, each pixel through `shared::integrator`, the same
//! function the GPU kernel runs, monomorphised for the scene's feature set (`variant`).
//! Non-finite samples are zeroed and logged with their pixel.
use crate::render::blocks::{Node, Sums, BLOCK_SAMPLES};
use crate::render::progressive::{Blocks, Progressive, RunningSums};
use crate::render::{adaptive, light_pool, Compiled, Progress, Rendered};
use crate::settings::{Aov, RenderSettings};
use anyhow::{bail, Result};
use rayon::prelude::*;
use shared::features::{
    connection_applies, FEATURES_ALL, FEATURE_ALPHA_MASKS, FEATURE_CONNECT, FEATURE_DIFFUSE, FEATURE_EMITTERS,
    FEATURE_ENVIRONMENT, FEATURE_ENVIRONMENT_MAP, FEATURE_INDIRECT, FEATURE_MANY_EMITTERS, FEATURE_MATERIALS,
    FEATURE_PUNCTUAL, FEATURE_TEXTURES, FEATURE_VERTEX_NORMALS,
};
use shared::glam::Vec4;
use shared::integrator::{render_pixels_for, PixelSpan};
use shared::lanes::integrator::render_pixels_for as lanes_render_pixels_for;
use shared::layout::{RayQuery, RayResult, RenderParams, NO_HIT};
use shared::raycast::cast_ray;
use shared::scene::SceneView;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// With a time limit, each pass after the first is sized to take 90% of the time left, but at
/// least this long while that much is left: the render ends close to its budget after a few
/// passes, and the passes are long enough for whole blocks (`block_aligned`).
const PASS_SECONDS: f64 = 0.25;
/// Adaptive sampling adds at most this many samples per pixel and pass, so that a time limit
/// is checked often.
const ADAPTIVE_PASS_SAMPLES: u32 = 16;

/// A monomorphised variant of the integrator: `render_pixels_for::<F>` (scene, parameters, the
/// row, its pixels' samples, the samples a run, the runs a pixel has at most, each pixel's runs'
/// sums and squared sums (run `r` of pixel `k` at `r * pixels + k`), the pixels' primary hits).
pub type VariantFn = fn(&SceneView, &RenderParams, u32, &[PixelSpan], u32, usize, &mut [Vec4], &mut [Vec4], &mut [u32]);

/// The compiled variants: every combination of the feature bits outside the materials and the
/// surface bits, each for diffuse alone and for every material kind, and all of those once
/// without and once with the surface bits; then the four that connect light subpaths
/// (`FEATURE_CONNECT`: Lambertian, emitting triangles and indirect light, with or without more
/// than one emitter and a constant environment) (`cpu_variant_bits`): `VARIANTS[i]` is
/// `render_pixels_for::<{ CANONICAL[i] }>`, and `LANE_VARIANTS[i]` the same through
/// `shared::lanes::integrator::render_pixels_for`, which renders sixteen samples at once (of one
/// pixel or of a few neighbours) and the same image bit for bit (it covers every variant).
macro_rules! variants {
    ($($bits:literal)*) => {
        #[cfg_attr(not(test), allow(dead_code))]
        const CANONICAL: [u32; 68] = [$($bits),*];
        static VARIANTS: [VariantFn; 68] = [$(render_pixels_for::<{ compiled($bits) }> as VariantFn),*];
        /// The same variants compiled for AVX-512 (`avx512::render_samples`).
        #[cfg(target_arch = "x86_64")]
        static VARIANTS_AVX512: [VariantFn; 68] =
            [$(avx512::render_samples::<{ compiled($bits) }> as VariantFn),*];
        static LANE_VARIANTS: [VariantFn; 68] = [$(lanes_render_pixels_for::<{ compiled($bits) }> as VariantFn),*];
        /// The same compiled for AVX-512 (`avx512::render_samples_lanes`).
        #[cfg(target_arch = "x86_64")]
        static LANE_VARIANTS_AVX512: [VariantFn; 68] =
            [$(avx512::render_samples_lanes::<{ compiled($bits) }> as VariantFn),*];
    };
}

/// The feature bits a table's entry is compiled for: `bits`, except in this library's own unit
/// tests, where every entry is the variant with every bit (the generic code, which renders every
/// scene's image bit for bit as its own variant does). No unit test renders through the tables;
/// the tests in `tests/` link the library as built and check each variant's image against the
/// generic one. The tables are four times 68 monomorphs of the integrator, most of the library's
/// machine code: compiled a second time for the unit tests, they made the tests' build minutes
/// longer (BENCHMARKS.md, "Building and testing").
const fn compiled(bits: u32) -> u32 {
    if cfg!(test) {
        FEATURES_ALL
    } else {
        bits
    }
}
variants!(
    8 9 10 11 12 13 14 15 24 25 26 27 28 29 30 12319
    488 489 490 491 492 493 494 495 504 505 506 507 508 509 510 12799
    3592 3593 3594 3595 3596 3597 3598 3599 3608 3609 3610 3611 3612 3613 3614 15903
    4072 4073 4074 4075 4076 4077 4078 4079 4088 4089 4090 4091 4092 4093 4094 32767
    16409 16411 16413 16415
);

/// Whether the CPU's variant comes from `LANE_VARIANTS`: unless the render is not specialised
/// (`--specialize off` runs the scalar integrator's generic code, the reference every variant is
/// tested against) or `KDTRACE_CPU_LANES=off` asks for the scalar integrator (to compare the
/// two).
fn lanes(specialize: bool) -> bool {
    specialize && std::env::var("KDTRACE_CPU_LANES").as_deref() != Ok("off")
}

/// Whether the CPU renders with `s` through the lane integrator: the radiance image with the
/// lanes' variant (`lanes`; an AOV runs the scalar integrator).
pub fn runs_lanes(s: &RenderSettings) -> bool {
    (s.aov == Aov::Radiance) && lanes(s.specialize)
}

/// The feature bits the CPU compiles a variant for, covering `bits`: the bits outside the
/// materials as they are, and diffuse alone or every material kind (a monomorph per material
/// set would multiply the variants with each kind; dispatch over the kinds present costs a
/// compare). Textures, alpha masks and vertex normals (`SURFACE`) are all on or all off: a scene
/// with any of them gets all three (one without the others costs a compare per hit), a scene
/// with none gets code without their checks and copies.
///
/// The environment map and punctual lights (`NEW_LIGHTS`) have no variants of their own: a scene
/// with either, or with every other light bit (`LIGHTS`), gets the variant with all of them,
/// which keeps the table at 64 and the four that connect light subpaths, which have the bits
/// `connection_applies` allows and no others.
pub fn cpu_variant_bits(bits: u32) -> u32 {
    if bits & FEATURE_CONNECT != 0 {
        // The connections apply to scenes of the bits their variants have; any other set with
        // them (the generic code) gets the variant with every bit.
        return if connection_applies(bits) { bits & FEATURES_ALL } else { FEATURES_ALL };
    }
    let surface = if bits & SURFACE != 0 { SURFACE } else { 0 };
    let mut rest = (bits & FEATURES_ALL & !FEATURE_MATERIALS & !SURFACE) | surface;
    if rest & NEW_LIGHTS != 0 || rest & LIGHTS == LIGHTS {
        rest |= LIGHTS | NEW_LIGHTS;
    }
    let b = if bits & FEATURE_MATERIALS == FEATURE_DIFFUSE { rest | FEATURE_DIFFUSE } else { rest | FEATURE_MATERIALS };
    // The variant with every other bit reads `RenderParams::connect` as well.
    if b == FEATURES_ALL & !FEATURE_CONNECT {
        FEATURES_ALL
    } else {
        b
    }
}

/// Emitters, several of them, a constant environment and indirect light.
const LIGHTS: u32 = FEATURE_EMITTERS | FEATURE_MANY_EMITTERS | FEATURE_ENVIRONMENT | FEATURE_INDIRECT;
/// The environment map and punctual lights: on only together with all of `LIGHTS`.
const NEW_LIGHTS: u32 = FEATURE_ENVIRONMENT_MAP | FEATURE_PUNCTUAL;

/// The surface bits, on or off together in a CPU variant (`cpu_variant_bits`).
const SURFACE: u32 = FEATURE_TEXTURES | FEATURE_ALPHA_MASKS | FEATURE_VERTEX_NORMALS;

/// Where `cpu_variant_bits(bits)` sits in `VARIANTS`: bits 0–2 and `FEATURE_INDIRECT` (bit 4)
/// count through 16, every material kind adds 16, the surface bits 32.
fn variant_index(bits: u32) -> usize {
    let b = cpu_variant_bits(bits);
    if (b & FEATURE_CONNECT != 0) & (b != FEATURES_ALL) {
        // After the 64: more than one emitter (bit 1) and the environment (bit 2) count to 4.
        return 64 + ((b >> 1) & 0b11) as usize;
    }
    let low = (b & 0b111) | ((b & FEATURE_INDIRECT) >> 1);
    let kinds = if b & FEATURE_MATERIALS != FEATURE_DIFFUSE { 16 } else { 0 };
    let surface = if b & SURFACE != 0 { 32 } else { 0 };
    (low + kinds + surface) as usize
}

/// The CPU's specialised variant of the integrator for feature bits `bits` (`cpu_variant_bits`),
/// compiled for AVX-512 where this CPU has it (`Isa::detect`).
pub fn variant(bits: u32) -> VariantFn {
    variant_for(bits, true, Isa::detect())
}

/// The variant that renders `c` with `s`: `variant` of the scene's feature bits, or with
/// `--specialize off` the scalar integrator's generic code.
fn variant_rendering(c: &Compiled, s: &RenderSettings) -> VariantFn {
    variant_for(crate::render::features::variant_bits(c, s), s.specialize, Isa::detect())
}

/// `variant` compiled for `isa`; `Isa::Avx512` only where the CPU has it (`Isa::detect`).
fn variant_for(bits: u32, specialize: bool, isa: Isa) -> VariantFn {
    let (i, lanes) = (variant_index(bits), lanes(specialize));
    match isa {
        Isa::Baseline if lanes => LANE_VARIANTS[i],
        Isa::Baseline => VARIANTS[i],
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 if lanes => LANE_VARIANTS_AVX512[i],
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => VARIANTS_AVX512[i],
    }
}

/// The instruction sets the CPU integrator is compiled for. The build's own target (x86-64-v3 on
/// x86-64, `.cargo/config.toml`) runs everywhere; the AVX-512 copy runs where the CPU has
/// AVX-512 F, VL, BW, DQ and CD (x86-64-v4). Its 32 vector registers hold the traversal's ray
/// constants without spilling them, and its compares write mask registers that become a bitmask
/// in one move. Every operation is the same IEEE single-precision one (Rust fuses nothing), so
/// the images are bit-identical (`tests/cli.rs`, `cpu_instruction_sets_render_the_same_image`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Isa {
    Baseline,
    #[cfg(target_arch = "x86_64")]
    Avx512,
}

impl Isa {
    /// AVX-512 where the CPU has it, unless `KDTRACE_CPU_ISA=baseline` asks for the build's
    /// own target (to compare the two).
    pub fn detect() -> Isa {
        #[cfg(target_arch = "x86_64")]
        if avx512::available() && std::env::var("KDTRACE_CPU_ISA").as_deref() != Ok("baseline") {
            return Isa::Avx512;
        }
        Isa::Baseline
    }

    /// The name `render --json` reports.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Baseline => BASELINE_NAME,
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => "x86-64-v4",
        }
    }
}

/// The CPU device's name in reports: its threads and the instruction set the integrator runs.
pub fn adapter_name(threads: usize) -> String {
    format!("cpu ({threads} threads, {})", Isa::detect().name())
}

/// Casts one ray of a batch (`shared::raycast::cast_ray`) compiled for `isa`.
pub fn cast_fn(isa: Isa) -> fn(&SceneView, &RayQuery) -> RayResult {
    match isa {
        Isa::Baseline => cast_ray,
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => avx512::cast_ray,
    }
}

/// Casts up to `shared::wide_packet::PACKET` rays of a batch at once
/// (`shared::raycast::cast_packet`) compiled for `isa`.
pub fn cast_packet_fn(isa: Isa) -> fn(&SceneView, &[RayQuery], &mut [RayResult]) {
    match isa {
        Isa::Baseline => shared::raycast::cast_packet,
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => avx512::cast_packet,
    }
}

/// The build's own target, as `render --json` names it.
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
const BASELINE_NAME: &str = "x86-64-v3";
#[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
const BASELINE_NAME: &str = "baseline";

/// The integrator's variants compiled for AVX-512.
#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::*;

    /// Whether this CPU runs `render_samples`.
    pub fn available() -> bool {
        std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vl")
            && std::arch::is_x86_feature_detected!("avx512bw")
            && std::arch::is_x86_feature_detected!("avx512dq")
            && std::arch::is_x86_feature_detected!("avx512cd")
    }

    /// `$integrator::<F>` in a function compiled for AVX-512 (`$compiled`), and `$name`, a
    /// `VariantFn` for it. The integrator, the traversal and the sampler are inlined into it
    /// (`#[inline(always)]` down the hot path), so they are compiled for AVX-512 too. `$name` is
    /// only in the AVX-512 tables, which `variant_for` hands out only for `Isa::Avx512`, which
    /// `Isa::detect` returns only where `available()`.
    macro_rules! avx512_variant {
        ($name:ident, $compiled:ident, $integrator:ident) => {
            #[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,avx512cd")]
            #[allow(clippy::too_many_arguments)]
            fn $compiled<const F: u32>(
                scene: &SceneView,
                p: &RenderParams,
                y: u32,
                pixels: &[PixelSpan],
                per: u32,
                runs: usize,
                sum: &mut [Vec4],
                sum_sq: &mut [Vec4],
                primary: &mut [u32],
            ) {
                $integrator::<F>(scene, p, y, pixels, per, runs, sum, sum_sq, primary)
            }

            #[allow(clippy::too_many_arguments)]
            pub fn $name<const F: u32>(
                scene: &SceneView,
                p: &RenderParams,
                y: u32,
                pixels: &[PixelSpan],
                per: u32,
                runs: usize,
                sum: &mut [Vec4],
                sum_sq: &mut [Vec4],
                primary: &mut [u32],
            ) {
                // SAFETY: see above: the CPU has every feature the function is compiled for.
                unsafe { $compiled::<F>(scene, p, y, pixels, per, runs, sum, sum_sq, primary) }
            }
        };
    }
    // The scalar integrator (`VARIANTS_AVX512`) and the lane integrator (`LANE_VARIANTS_AVX512`).
    avx512_variant!(render_samples, render_samples_avx512, render_pixels_for);
    avx512_variant!(render_samples_lanes, render_samples_lanes_avx512, lanes_render_pixels_for);

    /// `shared::raycast::cast_ray` compiled for AVX-512 (the wide BVH's traversal is inlined).
    #[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,avx512cd")]
    fn cast_ray_avx512(scene: &SceneView, q: &RayQuery) -> RayResult {
        shared::raycast::cast_ray(scene, q)
    }

    /// A plain function for `cast_ray_avx512`; `cast_fn` hands it out only for `Isa::Avx512`.
    pub fn cast_ray(scene: &SceneView, q: &RayQuery) -> RayResult {
        // SAFETY: as for `render_samples`.
        unsafe { cast_ray_avx512(scene, q) }
    }

    /// `shared::raycast::cast_packet` compiled for AVX-512.
    #[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,avx512cd")]
    fn cast_packet_avx512(scene: &SceneView, qs: &[RayQuery], out: &mut [RayResult]) {
        shared::raycast::cast_packet(scene, qs, out)
    }

    /// A plain function for `cast_packet_avx512`; `cast_packet_fn` hands it out only for
    /// `Isa::Avx512`.
    pub fn cast_packet(scene: &SceneView, qs: &[RayQuery], out: &mut [RayResult]) {
        // SAFETY: as for `render_samples`.
        unsafe { cast_packet_avx512(scene, qs, out) }
    }
}

/// Renders on the CPU: rayon over image rows, every pixel through `shared::integrator`. Without a
/// time limit all samples are one pass; with one, passes of whole samples for every pixel run
/// until the budget is spent, so every pixel has the same number of samples (unbiased).
pub fn render(c: &Compiled, s: &RenderSettings, progress: Progress) -> Result<Rendered> {
    s.check()?;
    let s = &RenderSettings { traversal: s.traversal.for_cpu_path(), ..*s };
    if s.traversal == crate::settings::Traversal::Wide && runs_lanes(s) {
        c.wide_bvh_and_split();
    }
    let (w, h) = (s.width, s.height);
    let n = (w * h) as usize;
    if let Some(a) = s.adaptive {
        let render_samples = variant_rendering(c, s);
        let params = c.params(s, 0, 0)?;
        let mut dev = CpuPasses {
            scene: c.view(&params),
            params,
            render_samples,
            width: w as usize,
            sum: vec![Vec4::ZERO; n],
            sum_sq: vec![Vec4::ZERO; n],
            primary: vec![NO_HIT; n],
        };
        let outcome = adaptive::render(&mut dev, s, a, progress)?;
        return Ok(Rendered {
            width: w,
            height: h,
            spp: s.spp,
            sum: dev.sum,
            sum_sq: dev.sum_sq,
            primary: dev.primary,
            traversal: s.traversal,
            counts: Some(outcome.counts),
        });
    }
    let mut passes = progressive(c, s)?;
    let total = w as u64 * h as u64 * s.spp as u64;
    let done = AtomicU64::new(0);
    let clock = Instant::now();
    let mut start = 0u32;
    let mut count = if s.time_limit_s.is_some() { 1 } else { s.spp };
    while start < s.spp {
        count = count.min(s.spp - start);
        let pass_clock = Instant::now();
        let row = |n: u32| {
            let k = w as u64 * n as u64;
            progress(done.fetch_add(k, Ordering::Relaxed) + k, total)
        };
        passes.pass_rows(start, count, &row)?;
        start += count;
        if let Some(limit) = s.time_limit_s {
            let elapsed = clock.elapsed().as_secs_f64();
            if elapsed >= limit {
                break;
            }
            // Size the next pass from this one's speed, within what is left of the budget.
            let per_sample = pass_clock.elapsed().as_secs_f64() / count as f64;
            let left = limit - elapsed;
            let fit = ((0.9 * left).max(PASS_SECONDS.min(left)) / per_sample.max(1e-9)).floor();
            count = block_aligned(start, (fit as u32).max(1));
        }
    }
    passes.into_image()
}

/// A pass of about `count` samples from `start`, shortened to end on a block boundary where
/// that leaves it a sample: its blocks are then whole, and two whole ones render in one sweep
/// with the lanes full (`RunningSums::add_two_blocks`). Any split gives the same image.
fn block_aligned(start: u32, count: u32) -> u32 {
    let end = start.saturating_add(count) / BLOCK_SAMPLES * BLOCK_SAMPLES;
    if end > start {
        end - start
    } else {
        count
    }
}

/// Starts a progressive render of `c` with `s` on the CPU (`progressive::Progressive`): the
/// sums allocated, the integrator's variant for the scene chosen. `s.spp`, `s.time_limit_s`
/// and `s.adaptive` are the caller's to apply (adaptive settings are refused).
pub fn progressive<'a>(c: &'a Compiled, s: &RenderSettings) -> Result<CpuProgressive<'a>> {
    let sums = CpuSums::new(c, s)?;
    let blocks = Blocks::new(sums.sum.len());
    Ok(CpuProgressive { sums, blocks })
}

/// The CPU's running sums of one block (`progressive::RunningSums`), added by rayon over rows.
pub(crate) struct CpuSums<'a> {
    c: &'a Compiled,
    /// The settings, the traversal resolved for the CPU.
    s: RenderSettings,
    /// `s`'s parameters, found once (`Compiled::params` analyses the scene); each pass sets its
    /// samples.
    params: RenderParams,
    render_samples: VariantFn,
    sum: Vec<Vec4>,
    sum_sq: Vec<Vec4>,
    primary: Vec<u32>,
    /// The second block's sums and squared sums of a pass that renders two blocks at once
    /// (`RunningSums::add_two_blocks`); empty until one does.
    next: (Vec<Vec4>, Vec<Vec4>),
}

impl<'a> CpuSums<'a> {
    pub(crate) fn new(c: &'a Compiled, s: &RenderSettings) -> Result<Self> {
        s.check()?;
        if s.adaptive.is_some() {
            bail!("a progressive render adds the same samples to every pixel: adaptive sampling does not apply");
        }
        let s = RenderSettings { traversal: s.traversal.for_cpu_path(), ..*s };
        let n = s.width as usize * s.height as usize;
        Ok(Self {
            c,
            params: c.params(&s, 0, 0)?,
            render_samples: variant_rendering(c, &s),
            s,
            sum: vec![Vec4::ZERO; n],
            sum_sq: vec![Vec4::ZERO; n],
            primary: vec![NO_HIT; n],
            next: (Vec::new(), Vec::new()),
        })
    }

    /// Adds samples `[start, start + count)` to every pixel's running sums, calling `row_done`
    /// with `count` after each row (from rayon's threads). With `two`, `count` is two blocks
    /// from a block boundary and the second block's samples go to the second block's sums
    /// (`next`, zeroed first), so the lane integrator fills its sixteen lanes from both.
    fn add_rows(&mut self, start: u32, count: u32, two: bool, row_done: &(dyn Fn(u32) + Sync)) -> Result<()> {
        let (c, w, render_samples) = (self.c, self.s.width as usize, self.render_samples);
        let params = RenderParams { sample_start: start, sample_count: count, ..self.params };
        let scene = c.view(&params);
        let (pool, first) = light_pool::pool_of(&scene, &params, start, start + count);
        let scene = light_pool::view(&scene, &pool, first);
        let n = self.sum.len();
        let (runs, per) = if two { (2, BLOCK_SAMPLES) } else { (1, count) };
        let (next, next_sq) = &mut self.next;
        if two {
            // Allocated by the first pass that renders two blocks at once.
            next.clear();
            next.resize(n, Vec4::ZERO);
            next_sq.clear();
            next_sq.resize(n, Vec4::ZERO);
        }
        let (start, count) = (params.sample_start, params.sample_count);
        let spans: Vec<PixelSpan> = (0..w as u32).map(|x| PixelSpan { x, start, count }).collect();
        let row = |y: usize,
                   sum: &mut [Vec4],
                   sum_sq: &mut [Vec4],
                   primary: &mut [u32],
                   next: Option<(&mut [Vec4], &mut [Vec4])>| {
            // The row's runs side by side: the first block's sums, then the second's.
            let (mut acc, mut acc_sq) = (sum.to_vec(), sum_sq.to_vec());
            if let Some((r, r_sq)) = &next {
                acc.extend_from_slice(r);
                acc_sq.extend_from_slice(r_sq);
            }
            let zeroed = |acc: &[Vec4], x: usize| (0..runs).map(|r| acc[r * w + x].w).sum::<f32>();
            let before: Vec<f32> = (0..w).map(|x| zeroed(&acc, x)).collect();
            render_samples(&scene, &params, y as u32, &spans, per, runs, &mut acc, &mut acc_sq, primary);
            sum.copy_from_slice(&acc[..w]);
            sum_sq.copy_from_slice(&acc_sq[..w]);
            if let Some((r, r_sq)) = next {
                r.copy_from_slice(&acc[w..]);
                r_sq.copy_from_slice(&acc_sq[w..]);
            }
            for (x, before) in before.into_iter().enumerate() {
                let after = zeroed(&acc, x);
                if after > before {
                    eprintln!("warning: pixel ({x}, {y}): {} non-finite or negative sample(s) zeroed", after - before);
                }
            }
            row_done(count);
        };
        let rows = self.sum.par_chunks_mut(w).zip(self.sum_sq.par_chunks_mut(w)).zip(self.primary.par_chunks_mut(w));
        if two {
            rows.zip(next.par_chunks_mut(w).zip(next_sq.par_chunks_mut(w)))
                .enumerate()
                .for_each(|(y, (((sum, sum_sq), primary), next))| row(y, sum, sum_sq, primary, Some(next)));
        } else {
            rows.enumerate().for_each(|(y, ((sum, sum_sq), primary))| row(y, sum, sum_sq, primary, None));
        }
        Ok(())
    }

    fn image(&self, spp: u32, sums: Sums) -> Rendered {
        Rendered {
            width: self.s.width,
            height: self.s.height,
            spp,
            sum: sums.sum,
            sum_sq: sums.sum_sq,
            primary: self.primary.clone(),
            traversal: self.s.traversal,
            counts: None,
        }
    }
}

/// `CpuSums` with a callback after each row, as `RunningSums`.
struct WithRows<'x, 'a>(&'x mut CpuSums<'a>, &'x (dyn Fn(u32) + Sync));

impl RunningSums for WithRows<'_, '_> {
    fn zero(&mut self) -> Result<()> {
        self.0.sum.fill(Vec4::ZERO);
        self.0.sum_sq.fill(Vec4::ZERO);
        Ok(())
    }

    fn add(&mut self, start: u32, count: u32) -> Result<()> {
        self.0.add_rows(start, count, false, self.1)
    }

    fn add_two_blocks(&mut self, first: u32) -> Result<[Sums; 2]> {
        self.zero()?;
        self.0.add_rows(first, 2 * BLOCK_SAMPLES, true, self.1)?;
        let first_block = self.read()?;
        // The running sums become the second block's.
        let (next, next_sq) = &mut self.0.next;
        std::mem::swap(&mut self.0.sum, next);
        std::mem::swap(&mut self.0.sum_sq, next_sq);
        Ok([first_block, self.read()?])
    }

    fn read(&mut self) -> Result<Sums> {
        Ok(Sums { sum: self.0.sum.clone(), sum_sq: self.0.sum_sq.clone() })
    }

    fn primary(&mut self) -> Result<Vec<u32>> {
        self.0.primary()
    }

    fn name(&self) -> String {
        self.0.name()
    }
}

impl RunningSums for CpuSums<'_> {
    fn zero(&mut self) -> Result<()> {
        WithRows(self, &|_| {}).zero()
    }

    fn add(&mut self, start: u32, count: u32) -> Result<()> {
        self.add_rows(start, count, false, &|_| {})
    }

    fn add_two_blocks(&mut self, first: u32) -> Result<[Sums; 2]> {
        WithRows(self, &|_| {}).add_two_blocks(first)
    }

    fn read(&mut self) -> Result<Sums> {
        WithRows(self, &|_| {}).read()
    }

    fn primary(&mut self) -> Result<Vec<u32>> {
        Ok(self.primary.clone())
    }

    fn name(&self) -> String {
        adapter_name(rayon::current_num_threads())
    }
}

/// A render in progress on the CPU (`progressive`): the running block's sums, passes of rayon
/// over rows, and the fold of the completed blocks.
pub struct CpuProgressive<'a> {
    sums: CpuSums<'a>,
    blocks: Blocks,
}

impl CpuProgressive<'_> {
    /// `pass`, calling `row_done` after each row with the samples it added to the row's pixels
    /// (from rayon's threads; a pass across blocks visits each row once per block).
    pub fn pass_rows(&mut self, start: u32, count: u32, row_done: &(dyn Fn(u32) + Sync)) -> Result<()> {
        self.blocks.pass(&mut WithRows(&mut self.sums, row_done), start, count)
    }

    /// The image accumulated so far.
    pub fn into_image(mut self) -> Result<Rendered> {
        self.image()
    }
}

impl Progressive for CpuProgressive<'_> {
    fn pass(&mut self, start: u32, count: u32) -> Result<()> {
        self.pass_rows(start, count, &|_| {})
    }

    fn image(&mut self) -> Result<Rendered> {
        let sums = self.blocks.total(&mut self.sums)?;
        Ok(self.sums.image(self.blocks.spp(), sums))
    }

    fn spp(&self) -> u32 {
        self.blocks.spp()
    }

    fn device(&self) -> String {
        self.sums.name()
    }

    fn start_at(&mut self, start: u32) -> Result<()> {
        self.blocks.start_at(start)
    }

    fn nodes(&mut self) -> Result<Vec<Node>> {
        self.blocks.nodes(&mut self.sums)
    }
}

/// Adaptive sampling's passes on the CPU: rayon over rows, each pixel its own range.
struct CpuPasses<'a> {
    scene: SceneView<'a>,
    params: RenderParams,
    render_samples: VariantFn,
    width: usize,
    sum: Vec<Vec4>,
    sum_sq: Vec<Vec4>,
    primary: Vec<u32>,
}

impl adaptive::Passes for CpuPasses<'_> {
    fn pass(&mut self, ranges: &[[u32; 2]]) -> Result<()> {
        let (w, params, f) = (self.width, &self.params, self.render_samples);
        let (start, end) = adaptive::sample_span(ranges.iter().copied());
        let (pool, first) = light_pool::pool_of(&self.scene, params, start, end);
        let scene = &light_pool::view(&self.scene, &pool, first);
        self.sum
            .par_chunks_mut(w)
            .zip(self.sum_sq.par_chunks_mut(w))
            .zip(self.primary.par_chunks_mut(w))
            .zip(ranges.par_chunks(w))
            .enumerate()
            .for_each(|(y, (((sum, sum_sq), primary), ranges))| {
                let spans: Vec<PixelSpan> =
                    ranges.iter().zip(0..).map(|(&[start, count], x)| PixelSpan { x, start, count }).collect();
                // Each pixel's samples are one run.
                f(scene, params, y as u32, &spans, u32::MAX, 1, sum, sum_sq, primary);
            });
        Ok(())
    }

    fn max_per_pass(&self) -> u32 {
        ADAPTIVE_PASS_SAMPLES
    }

    fn sums(&mut self) -> Result<Vec<Vec4>> {
        Ok(self.sum.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_limited_passes_end_on_block_boundaries_where_they_can() {
        assert_eq!(block_aligned(1, 40), 39);
        assert_eq!(block_aligned(0, 16), 16);
        assert_eq!(block_aligned(8, 20), 16);
        // Too short to reach the next boundary: as asked.
        assert_eq!(block_aligned(1, 5), 5);
        assert_eq!(block_aligned(9, 1), 1);
        assert_eq!(block_aligned(u32::MAX - 3, 10), 10);
    }

    #[test]
    fn every_feature_set_finds_the_variant_compiled_for_it() {
        for bits in 0..=FEATURES_ALL {
            let i = variant_index(bits);
            assert_eq!(CANONICAL[i], cpu_variant_bits(bits), "feature bits {bits:#b}");
            // The variant covers the set: it leaves out nothing the scene uses.
            assert_eq!(CANONICAL[i] & bits, bits & FEATURES_ALL);
        }
        for (i, &c) in CANONICAL.iter().enumerate() {
            assert_eq!(variant_index(c), i);
        }
    }

    #[test]
    fn the_lane_integrator_covers_every_variant() {
        for (i, &c) in CANONICAL.iter().enumerate() {
            assert!(shared::lanes::integrator::covers(c), "variant {i}: bits {c:#b}");
        }
    }
}
