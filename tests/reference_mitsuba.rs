//! kdtrace against an independent renderer: our Cornell box rendered by Mitsuba 3
//! (tests/data/cornell-box-mitsuba-32.exr, 131072 spp, made by bench/peers/make_test_reference.sh)
//! and by kdtrace on the CPU with the same camera, 6 bounces and Russian roulette from bounce 5.
//!
//! Statistics: kdtrace renders K = 16 independent images (seeds 1..=16) of N = 256 spp each. Per
//! pixel channel, the K image values are K independent, identically distributed estimates; their
//! mean m and unbiased variance s² give the one-sample t statistic t = (m − r) / √(s²/K) with
//! K − 1 degrees of freedom against the reference value r (`kdtrace::image::metrics::mean_test`). The
//! reference has its own noise: its standard error e per pixel (from 16 chunks, stored beside
//! it) is added in quadrature, t = (m − r) / √(s²/K + e²) (e is about 1/6 of √(s²/K) here).
//! All 3·32·32 = 3072 channel tests are made at the Šidák level 1 − (1 − α)^(1/3072) with
//! α = 0.01, so the chance that a correct renderer fails anywhere is 1%. With fixed seeds the
//! outcome is deterministic. Besides, the mean over the image must be within 1% of Mitsuba's.
//! Both checks are shown to fail on a wrong reference (mirrored, or 2% brighter).
//! The materials, the textured wall and the environment map have references of their own made
//! the same way (`make_test_reference.sh MODE`).
use kdtrace::{
    image::{
        io::read_exr,
        metrics::{pixel_test, pointwise, LinearImage, PixelStats, PixelTest},
    },
    kdbuild::BuildSettings,
    render::cpu,
    settings::{camera::Camera, Adaptive, AdaptiveMode, RenderSettings},
};
use shared::glam::DVec3;
use std::path::PathBuf;

const SIZE: u32 = 32;
const SEEDS: u32 = 16;
const SPP: u32 = 256;
const ALPHA: f64 = 0.01;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn read(name: &str) -> LinearImage {
    let (w, h, px) = read_exr(&root().join("tests/data").join(name)).unwrap();
    LinearImage::new(w, h, px).unwrap()
}

/// Mean and unbiased variance over seeds of kdtrace's image, per pixel channel; with
/// `adaptive`, of adaptive renders (each seed's image is still one independent estimate).
fn kdtrace_seed_statistics(scene: &str, adaptive: Option<Adaptive>) -> (LinearImage, LinearImage) {
    let loaded = kdtrace::load(&root().join(scene), BuildSettings::default()).unwrap();
    seed_statistics(&loaded.compiled, adaptive)
}

/// `kdtrace_seed_statistics` of a compiled scene.
fn seed_statistics(compiled: &kdtrace::render::Compiled, adaptive: Option<Adaptive>) -> (LinearImage, LinearImage) {
    let camera = Camera {
        eye: DVec3::new(0.278, 0.273, 0.8),
        target: DVec3::new(0.278, 0.273, 0.0),
        up: DVec3::Y,
        fov_deg: 39.3076,
    };
    seed_statistics_from(compiled, adaptive, camera)
}

/// `seed_statistics` seen through `camera`.
fn seed_statistics_from(
    compiled: &kdtrace::render::Compiled,
    adaptive: Option<Adaptive>,
    camera: Camera,
) -> (LinearImage, LinearImage) {
    let images: Vec<Vec<[f32; 3]>> = (1..=SEEDS)
        .map(|seed| {
            let s = RenderSettings {
                width: SIZE,
                height: SIZE,
                spp: SPP,
                max_bounces: 6,
                seed,
                rr_start: 5,
                adaptive,
                sampler: if std::env::var("DEBUG_INDEP").is_ok() {
                    kdtrace::settings::SamplerKind::Independent
                } else {
                    Default::default()
                },
                ..RenderSettings::with_camera(camera)
            };
            let r = cpu::render(compiled, &s, &|_, _| {}).unwrap();
            assert_eq!(r.zeroed_samples(), 0);
            r.mean()
        })
        .collect();
    let stats = PixelStats::of_images(SIZE, SIZE, &images).unwrap();
    (stats.mean, stats.variance)
}

/// The per-pixel test with the reference's standard error folded into the variance:
/// s²/K + e² = (s² + K·e²)/K.
fn test_against(reference: &LinearImage, stderr: &LinearImage, mean: &LinearImage, var: &LinearImage) -> PixelTest {
    test_within(reference, stderr, mean, var, 0.0)
}

/// `test_against` with a numerical tolerance: `rounding` × the reference value joins each
/// pixel's standard error in quadrature, for pixels whose estimate is nearly noise-free (the sky
/// seen directly), where two renderers' float arithmetic would otherwise be what is tested.
fn test_within(
    reference: &LinearImage,
    stderr: &LinearImage,
    mean: &LinearImage,
    var: &LinearImage,
    rounding: f32,
) -> PixelTest {
    let k = SEEDS as f32;
    let variance = LinearImage::new(
        SIZE,
        SIZE,
        var.pixels
            .iter()
            .zip(&stderr.pixels)
            .zip(&reference.pixels)
            .map(|((v, e), r)| [0, 1, 2].map(|c| v[c] + k * (e[c] * e[c] + (rounding * r[c]).powi(2))))
            .collect(),
    )
    .unwrap();
    let stats = PixelStats { mean: mean.clone(), variance, count: vec![SEEDS as u64; (SIZE * SIZE) as usize] };
    pixel_test(reference, &stats, ALPHA).unwrap()
}

#[test]
fn cornell_box_matches_mitsuba_per_pixel_and_in_mean() {
    let reference = read("cornell-box-mitsuba-32.exr");
    let stderr = read("cornell-box-mitsuba-32-stderr.exr");
    assert_eq!((reference.width, reference.height), (SIZE, SIZE));
    let (mean, var) = kdtrace_seed_statistics("scenes/cornell-box.obj", None);

    let (_, _, _, ratio, _) = pointwise(&reference, &mean).unwrap();
    let t = test_against(&reference, &stderr, &mean, &var);
    eprintln!("mean ratio kdtrace/Mitsuba {ratio:.5}; per-pixel test: {t:?}");
    assert!((ratio - 1.0).abs() < 0.01, "image mean ratio {ratio}");
    assert!(t.pass && t.tests == 3 * (SIZE * SIZE) as u64, "{t:?}");

    // The same checks reject a wrong reference: mirrored left to right (red and green walls
    // swap sides) fails per pixel, 2% brighter fails the mean.
    let mirrored = LinearImage::new(
        SIZE,
        SIZE,
        (0..SIZE * SIZE).map(|i| reference.pixels[((i / SIZE) * SIZE + SIZE - 1 - i % SIZE) as usize]).collect(),
    )
    .unwrap();
    let bad = test_against(&mirrored, &stderr, &mean, &var);
    assert!(!bad.pass && bad.rejected > 100, "mirrored reference accepted: {bad:?}");
    let brighter =
        LinearImage::new(SIZE, SIZE, reference.pixels.iter().map(|p| p.map(|c| c * 1.02)).collect()).unwrap();
    let (_, _, _, ratio_bright, _) = pointwise(&brighter, &mean).unwrap();
    assert!((ratio_bright - 1.0).abs() > 0.01, "2% brighter reference accepted: ratio {ratio_bright}");
}

/// Adaptive sampling's unbiased mode passes the same per-pixel test: its budgets come from a
/// pilot whose samples the image does not average.
#[test]
fn adaptive_pilot_mode_matches_mitsuba_per_pixel() {
    let reference = read("cornell-box-mitsuba-32.exr");
    let stderr = read("cornell-box-mitsuba-32-stderr.exr");
    let adaptive = Adaptive { threshold: 0.05, min_spp: 16, mode: AdaptiveMode::Pilot };
    let (mean, var) = kdtrace_seed_statistics("scenes/cornell-box.obj", Some(adaptive));
    let (_, _, _, ratio, _) = pointwise(&reference, &mean).unwrap();
    let t = test_against(&reference, &stderr, &mean, &var);
    eprintln!("adaptive (pilot): mean ratio kdtrace/Mitsuba {ratio:.5}; per-pixel test: {t:?}");
    assert!((ratio - 1.0).abs() < 0.01, "image mean ratio {ratio}");
    assert!(t.pass && t.tests == 3 * (SIZE * SIZE) as u64, "{t:?}");
}

/// A rough conductor against Mitsuba's `roughconductor` (GGX α 0.2, gold): the Cornell box with
/// its tall block in gold (tests/data/cornell-metal, reference by
/// `bench/peers/make_test_reference.sh metal`), the same per-pixel test and mean.
#[test]
fn rough_gold_matches_mitsuba_per_pixel() {
    let reference = read("cornell-metal/cornell-metal-mitsuba-32.exr");
    let stderr = read("cornell-metal/cornell-metal-mitsuba-32-stderr.exr");
    let (mean, var) = kdtrace_seed_statistics("tests/data/cornell-metal/cornell-metal.toml", None);
    let (_, _, _, ratio, _) = pointwise(&reference, &mean).unwrap();
    let t = test_against(&reference, &stderr, &mean, &var);
    eprintln!("rough gold: mean ratio kdtrace/Mitsuba {ratio:.5}; per-pixel test: {t:?}");
    assert!((ratio - 1.0).abs() < 0.01, "image mean ratio {ratio}");
    assert!(t.pass && t.tests == 3 * (SIZE * SIZE) as u64, "{t:?}");
    // The tall block's pixels differ from the diffuse box's: the test sees the metal.
    let changed = pixels_unlike_the_box(&reference, 1);
    assert!(changed > 40, "only {changed} pixels differ from the diffuse box");
}

/// How many pixels of `reference` differ from the plain diffuse box's reference by more than 5%
/// in `channel`: a reference that did not show the material would pass the tests trivially.
fn pixels_unlike_the_box(reference: &LinearImage, channel: usize) -> usize {
    let plain = read("cornell-box-mitsuba-32.exr");
    let c = channel;
    reference.pixels.iter().zip(&plain.pixels).filter(|(a, b)| (a[c] - b[c]).abs() > 0.05 * b[c].max(0.01)).count()
}

/// The test of `test_against` on `block`×`block` squares of kdtrace's statistics `(mean, var)`
/// against the reference `NAME` of tests/data/cornell-materials.
fn block_test(name: &str, block: u32, mean: &LinearImage, var: &LinearImage) -> PixelTest {
    let reference = read(&format!("cornell-materials/cornell-{name}-mitsuba-32.exr"));
    let stderr = read(&format!("cornell-materials/cornell-{name}-mitsuba-32-stderr.exr"));
    let side = SIZE / block;
    let square =
        |e: &LinearImage| LinearImage::new(SIZE, SIZE, e.pixels.iter().map(|p| p.map(|x| x * x)).collect()).unwrap();
    // Per block: the mean of its pixels; the variance of that mean, Σ var / block⁴.
    let (r, m) = (blocks(&reference, block), blocks(mean, block));
    let scale = 1.0 / (block * block) as f32;
    let (v, e2) = (blocks(var, block), blocks(&square(&stderr), block));
    let k = SEEDS as f32;
    let variance = LinearImage::new(
        side,
        side,
        v.pixels.iter().zip(&e2.pixels).map(|(v, e2)| [0, 1, 2].map(|c| (v[c] + k * e2[c]) * scale)).collect(),
    )
    .unwrap();
    let stats = PixelStats { mean: m, variance, count: vec![SEEDS as u64; (side * side) as usize] };
    pixel_test(&r, &stats, ALPHA).unwrap()
}

/// Each `block`×`block` square's mean.
fn blocks(image: &LinearImage, block: u32) -> LinearImage {
    let side = SIZE / block;
    let pixels = (0..side * side)
        .map(|b| {
            let (bx, by) = (b % side, b / side);
            let mut acc = [0f32; 3];
            for y in by * block..(by + 1) * block {
                for x in bx * block..(bx + 1) * block {
                    let p = image.pixels[(y * SIZE + x) as usize];
                    acc = [0, 1, 2].map(|c| acc[c] + p[c]);
                }
            }
            acc.map(|a| a / (block * block) as f32)
        })
        .collect();
    LinearImage::new(side, side, pixels).unwrap()
}

/// The tall block in another material (tests/data/cornell-materials, references by
/// `bench/peers/make_test_reference.sh NAME`): the image mean within 1%, `block_test`, and the
/// block's pixels differ from the diffuse box's, so the test sees the material.
fn block_matches_mitsuba(name: &str, block: u32) {
    let reference = read(&format!("cornell-materials/cornell-{name}-mitsuba-32.exr"));
    let (mean, var) = kdtrace_seed_statistics(&format!("tests/data/cornell-materials/cornell-{name}.toml"), None);
    let (_, _, _, ratio, _) = pointwise(&reference, &mean).unwrap();
    let t = block_test(name, block, &mean, &var);
    eprintln!("{name}: mean ratio kdtrace/Mitsuba {ratio:.5}; {block}×{block} test: {t:?}");
    assert!((ratio - 1.0).abs() < 0.01, "{name}: image mean ratio {ratio}");
    assert!(t.pass && t.tests == 3 * (SIZE / block).pow(2) as u64, "{name}: {t:?}");
    let changed = pixels_unlike_the_box(&reference, 1);
    assert!(changed > 40, "{name}: only {changed} pixels differ from the diffuse box");
}

/// Plastic against Mitsuba's `plastic` (`nonlinear = false`, index 1.5), pixel by pixel.
#[test]
fn plastic_matches_mitsuba_per_pixel() {
    block_matches_mitsuba("plastic", 1);
}

/// Rough plastic against Mitsuba's `roughplastic` (GGX α 0.2, index 1.5, `nonlinear = false`),
/// pixel by pixel.
#[test]
fn rough_plastic_matches_mitsuba_per_pixel() {
    block_matches_mitsuba("roughplastic", 1);
}

/// Rough glass against Mitsuba's `roughdielectric` (GGX α 0.2, index 1.5), on 8×8 blocks: light
/// focused through the glass (caustics) makes single pixels' estimates heavy-tailed, and their
/// standard errors from 16 seeds (and the reference's from 16 chunks) too small. Measured: with
/// 131072 spp of kdtrace against the reference, single pixels deviated with both signs alike
/// (up to 12 of the reference's standard errors, in a corner caustic) and the image mean was
/// 0.9992 of Mitsuba's.
#[test]
fn rough_glass_matches_mitsuba_per_block() {
    block_matches_mitsuba("glass", 8);
    // The blocks see the glass's roughness: smooth glass (a sharper caustic, clear instead of
    // frosted) is rejected.
    let mut smooth =
        kdtrace::load(&root().join("tests/data/cornell-materials/cornell-glass.toml"), BuildSettings::default())
            .unwrap();
    for m in &mut smooth.compiled.scene.materials {
        if m.kind == shared::layout::MATERIAL_DIELECTRIC {
            m.params.x = 0.0;
        }
    }
    let (mean, var) = seed_statistics(&smooth.compiled, None);
    let t = block_test("glass", 8, &mean, &var);
    assert!(!t.pass, "smooth glass passed as rough: {t:?}");
}

/// Smooth glass against Mitsuba's `dielectric` (index 1.5), on 8×8 blocks as the rough glass:
/// its caustics are reached by BSDF sampling alone.
#[test]
fn smooth_glass_matches_mitsuba_per_block() {
    block_matches_mitsuba("smooth-glass", 8);
}

/// A texture against Mitsuba's `bitmap`: the Cornell box with a 4×4-texel sRGB poster on its back
/// wall (tests/data/cornell-textured, reference by `bench/peers/make_test_reference.sh textured`:
/// bilinear filtering, repeat wrapping, sRGB decoding), the same per-pixel test and mean; the
/// poster's pixels differ from the plain box's, so the test sees the texture (a poster read upside
/// down or mirrored would fail it: its rows and columns differ).
#[test]
fn textured_wall_matches_mitsuba_per_pixel() {
    let reference = read("cornell-textured/cornell-textured-mitsuba-32.exr");
    let stderr = read("cornell-textured/cornell-textured-mitsuba-32-stderr.exr");
    let (mean, var) = kdtrace_seed_statistics("tests/data/cornell-textured/cornell-textured.toml", None);
    let (_, _, _, ratio, _) = pointwise(&reference, &mean).unwrap();
    let t = test_against(&reference, &stderr, &mean, &var);
    eprintln!("textured wall: mean ratio kdtrace/Mitsuba {ratio:.5}; per-pixel test: {t:?}");
    assert!((ratio - 1.0).abs() < 0.01, "image mean ratio {ratio}");
    assert!(t.pass && t.tests == 3 * (SIZE * SIZE) as u64, "{t:?}");
    let changed = pixels_unlike_the_box(&reference, 2);
    assert!(changed > 100, "only {changed} pixels differ from the plain box");
}

/// Environment lighting: a floor and a block under an equirectangular sky with a small bright
/// sun, rotated 30° about y (tests/data/environment), against Mitsuba 3's `envmap` with the same
/// rotation: per pixel (the sky seen directly, the sun's shadow, the sky's light on the block)
/// and in mean. The sky seen directly is all but noise-free in both renderers; there our
/// polynomial acos and atan2 and Mitsuba's differ by up to 6e-5 relative where the map's
/// horizon steps from sky to ground, so the test allows 1e-4 relative for rounding. The same map
/// turned the other way (−30°) fails the per-pixel test, so the test sees the mapping and the
/// rotation.
#[test]
fn environment_map_matches_mitsuba_per_pixel() {
    const ROUNDING: f32 = 1e-4;
    let reference = read("environment/sky-scene-mitsuba-32.exr");
    let stderr = read("environment/sky-scene-mitsuba-32-stderr.exr");
    let mut loaded =
        kdtrace::load(&root().join("tests/data/environment/sky-scene.toml"), BuildSettings::default()).unwrap();
    let camera =
        Camera { eye: DVec3::new(2.2, 1.0, 2.6), target: DVec3::new(0.0, 0.5, 0.0), up: DVec3::Y, fov_deg: 45.0 };
    let (mean, var) = seed_statistics_from(&loaded.compiled, None, camera);
    let (_, _, _, ratio, _) = pointwise(&reference, &mean).unwrap();
    let t = test_within(&reference, &stderr, &mean, &var, ROUNDING);
    eprintln!("environment map: mean ratio kdtrace/Mitsuba {ratio:.5}; per-pixel test: {t:?}");
    assert!((ratio - 1.0).abs() < 0.01, "image mean ratio {ratio}");
    assert!(t.pass && t.tests == 3 * (SIZE * SIZE) as u64, "{t:?}");

    let map = loaded.compiled.scene.environment_map.as_mut().unwrap();
    assert_eq!(map.rotate, [0.0, 30.0, 0.0]);
    map.rotate = [0.0, -30.0, 0.0];
    loaded.compiled.prepare_emitters();
    let (turned, turned_var) = seed_statistics_from(&loaded.compiled, None, camera);
    let bad = test_within(&reference, &stderr, &turned, &turned_var, ROUNDING);
    eprintln!("the map turned the other way: {bad:?}");
    assert!(!bad.pass && bad.rejected > 50, "a map turned the other way passed: {bad:?}");
}
