//! Single source, proven: the GPU kernel and the CPU reference, same seed and scene. On lavapipe
//! (opened by name; missing lavapipe is a failure, not a skip) the images and primary hits are
//! identical bit for bit. Every other adapter present (a real GPU fuses multiply-adds and rounds
//! division its own way) must agree within 1e-3 relative on ≥ 99.9% of pixels and hit the same
//! primary triangle on ≥ 99.99%, `kdtrace verify`'s bound. Any divergence is counted and printed.
#[path = "common/paths.rs"]
mod paths;
use kdtrace::{
    kdbuild::BuildSettings,
    load,
    render::{
        cpu, gpu,
        verify::{compare, MIN_PIXEL_SHARE, MIN_PRIMARY_SHARE},
        Compiled,
    },
    settings::{camera::Camera, RenderSettings},
};
use paths::{mesh, repo};
use shared::glam::DVec3;

fn no_progress(_: u64, _: u64) {}

fn agree_on(c: &Compiled, s: &RenderSettings, what: &str) {
    let cpu_img = cpu::render(c, s, &no_progress).unwrap();
    // The images are not trivially equal: the scene is lit and noisy.
    let mean: f32 = cpu_img.mean().iter().map(|p| p[0] + p[1] + p[2]).sum::<f32>() / cpu_img.mean().len() as f32;
    assert!(mean > 0.01, "{what}: image is black");
    assert_eq!(cpu_img.zeroed_samples(), 0);
    let lavapipe = gpu::Gpu::lavapipe().unwrap_or_else(|e| panic!("{e:#}"));
    let others = gpu::adapters().into_iter().filter(|a| !a.name.to_lowercase().contains(gpu::LAVAPIPE));
    for g in std::iter::once(lavapipe).chain(others.filter_map(|a| gpu::Gpu::open(Some(&a.name)).ok())) {
        let gpu_img = g.render(c, s, &no_progress).unwrap();
        let a = compare(&cpu_img, &gpu_img);
        eprintln!(
            "{what} on {}: {}/{} pixels within 1e-3 ({} bit-identical), relMSE {:.3e}, primary {}/{}, first divergence {:?}",
            g.adapter.name,
            a.pixels_within,
            a.pixels,
            a.bitwise_identical_pixels,
            a.relmse,
            a.primary_matches,
            a.pixels,
            a.first_divergent
        );
        assert_eq!(gpu_img.zeroed_samples(), 0);
        if g.is_lavapipe() {
            assert_eq!(a.bitwise_identical_pixels, a.pixels, "{what}: lavapipe's image differs from the CPU's");
            assert_eq!(a.primary_matches, a.pixels, "{what}: lavapipe's primary hits differ from the CPU's");
        } else {
            assert!(a.pixel_share >= MIN_PIXEL_SHARE, "{what}: only {:.4}% of pixels agree", 100.0 * a.pixel_share);
            assert!(
                a.primary_share >= MIN_PRIMARY_SHARE,
                "{what}: only {:.4}% of primary hits agree",
                100.0 * a.primary_share
            );
            assert!(a.pass);
        }
    }
}

#[test]
fn our_cornell_box_agrees_at_64x64_16spp() {
    let c = load(&repo("scenes/cornell-box.obj"), BuildSettings::default()).unwrap().compiled;
    let camera = Camera {
        eye: DVec3::new(0.278, 0.273, 0.8),
        target: DVec3::new(0.278, 0.273, 0.0),
        up: DVec3::Y,
        fov_deg: 39.3076,
    };
    let s = RenderSettings {
        width: 64,
        height: 64,
        spp: 16,
        max_bounces: 6,
        seed: 1,
        rr_start: 5,
        ..RenderSettings::with_camera(camera)
    };
    agree_on(&c, &s, "scenes/cornell-box.obj");
}

#[test]
fn cornell_box_sphere_agrees() {
    let path = mesh("CornellBox-Sphere/CornellBox-Sphere.obj");
    assert!(path.exists(), "{} is missing", path.display());
    let c = load(&path, BuildSettings::default()).unwrap().compiled;
    let camera =
        Camera { eye: DVec3::new(0.0, 1.0, 3.4), target: DVec3::new(0.0, 1.0, 0.0), up: DVec3::Y, fov_deg: 39.3 };
    let s = RenderSettings {
        width: 48,
        height: 48,
        spp: 8,
        max_bounces: 4,
        seed: 9,
        rr_start: 3,
        ..RenderSettings::with_camera(camera)
    };
    agree_on(&c, &s, "CornellBox-Sphere");
}

/// Deep paths, many samples per pixel, thousands of triangles: the case that diverged on
/// lavapipe when one invocation traced all 16 samples in one dispatch and ran past gallivm's
/// 65535-iteration loop limit (whole subgroups lost their later samples).
#[test]
fn water_box_agrees_with_many_samples_per_pixel() {
    let path = mesh("CornellBox-Water/CornellBox-Water.obj");
    assert!(path.exists(), "{} is missing", path.display());
    let c = load(&path, BuildSettings::default()).unwrap().compiled;
    let camera =
        Camera { eye: DVec3::new(0.0, 1.0, 3.4), target: DVec3::new(0.0, 1.0, 0.0), up: DVec3::Y, fov_deg: 39.3076 };
    let s = RenderSettings {
        width: 64,
        height: 64,
        spp: 16,
        max_bounces: 6,
        seed: 0,
        rr_start: 5,
        ..RenderSettings::with_camera(camera)
    };
    agree_on(&c, &s, "CornellBox-Water");
}
