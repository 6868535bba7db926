//! Analytic scenes (pbrt's integrators_test.cpp in spirit): the white furnace, where every
//! bounce count has a closed form, and one-sided emission seen from the front and the back.
use kdtrace::{
    compile,
    kdbuild::BuildSettings,
    render::{cpu, gpu, Compiled, Rendered},
    scene::procedural,
    settings::{camera::Camera, RenderSettings},
};
use shared::glam::{DVec3, Vec3};

fn settings(size: u32, spp: u32, bounces: u32, camera: Camera) -> RenderSettings {
    RenderSettings {
        width: size,
        height: size,
        spp,
        max_bounces: bounces,
        seed: 7,
        rr_start: 3,
        ..RenderSettings::with_camera(camera)
    }
}

fn inside_camera() -> Camera {
    Camera { eye: DVec3::new(0.1, -0.2, 0.3), target: DVec3::new(0.5, 0.4, -1.0), up: DVec3::Y, fov_deg: 90.0 }
}

fn image_mean(r: &Rendered) -> (f64, f64, f64) {
    let m = r.mean();
    let n = m.len() as f64;
    let (min, max) =
        m.iter().flat_map(|p| p.iter()).fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v as f64), b.max(v as f64)));
    (m.iter().map(|p| (p[0] + p[1] + p[2]) as f64 / 3.0).sum::<f64>() / n, min, max)
}

fn no_progress(_: u64, _: u64) {}

fn furnace(albedo: f32) -> Compiled {
    compile(procedural::furnace(albedo, 1.0).unwrap(), BuildSettings::default())
}

/// Le · Σ_{k=0}^{B+1} a^k: the camera sees emission, then one more term per bounce, and the
/// direct-light term counts as the first (`max_bounces` counts indirect bounces only).
fn truncated_series(albedo: f64, bounces: u32) -> f64 {
    (0..=bounces + 1).map(|k| albedo.powi(k as i32)).sum()
}

#[test]
fn white_furnace_converges_to_le_over_one_minus_albedo() {
    let albedo = 0.7;
    let c = furnace(albedo as f32);
    let r = cpu::render(&c, &settings(32, 64, 200, inside_camera()), &no_progress).unwrap();
    let (mean, min, max) = image_mean(&r);
    let expected = 1.0 / (1.0 - albedo);
    assert!((mean / expected - 1.0).abs() < 0.01, "furnace mean {mean}, expected {expected}");
    // Every pixel sees the same radiance; with roulette noise each stays within 50%.
    assert!(min > 0.5 * expected && max < 1.5 * expected, "pixel range [{min}, {max}] around {expected}");
    assert_eq!(r.zeroed_samples(), 0);
}

#[test]
fn bounce_limit_truncates_the_series_exactly_in_expectation() {
    let albedo = 0.5;
    let c = furnace(albedo as f32);
    for bounces in [0u32, 1, 2] {
        let r = cpu::render(&c, &settings(32, 32, bounces, inside_camera()), &no_progress).unwrap();
        let (mean, _, _) = image_mean(&r);
        let expected = truncated_series(albedo, bounces);
        assert!((mean / expected - 1.0).abs() < 0.01, "B={bounces}: mean {mean}, expected {expected}");
        // One more bounce would add albedo^(B+2), ≥ 3% here: the 1% band excludes it.
        let wrong = truncated_series(albedo, bounces + 1);
        assert!((mean / wrong - 1.0).abs() > 0.015, "B={bounces} looks like B+1");
    }
}

#[test]
fn furnace_on_the_gpu_matches_the_analytic_value() {
    let albedo = 0.5;
    let c = furnace(albedo as f32);
    let g = gpu::Gpu::open(None).expect("a Vulkan adapter (lavapipe in CI: scripts/setup.sh installs it)");
    let r = g.render(&c, &settings(16, 32, 2, inside_camera()), &no_progress).unwrap();
    let (mean, _, _) = image_mean(&r);
    let expected = truncated_series(albedo, 2);
    assert!((mean / expected - 1.0).abs() < 0.01, "GPU furnace mean {mean}, expected {expected}");
}

#[test]
fn emission_is_one_sided_from_the_counter_clockwise_side() {
    let le = Vec3::new(3.0, 2.0, 1.0);
    let camera = Camera { eye: DVec3::new(0.0, 0.0, 5.0), target: DVec3::ZERO, up: DVec3::Y, fov_deg: 10.0 };
    for facing in [true, false] {
        let c = compile(procedural::emitter(le, facing).unwrap(), BuildSettings::default());
        let r = cpu::render(&c, &settings(8, 4, 0, camera), &no_progress).unwrap();
        // The 10° view at distance 5 sees only the 2×2 emitter: every pixel is Le or black.
        for p in r.mean() {
            let expected = if facing { le } else { Vec3::ZERO };
            assert_eq!(Vec3::from(p), expected, "facing camera: {facing}");
        }
    }
}
