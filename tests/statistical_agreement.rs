//! Statistics of whole images: the CPU and the GPU, rendering the same scene with different
//! seeds, agree pixel by pixel under Welch's t-test with Šidák's correction (α = 0.01) — the test
//! that still means something on a real GPU, where a float comparison may flip and paths
//! diverge. `--time-limit` stops on whole samples: the image equals a fixed-spp render of the spp
//! it reached. `render --variance` and `compare --variance` test a render against a converged
//! reference from the command line.
use kdtrace::{
    compile,
    image::metrics::two_image_test,
    kdbuild::BuildSettings,
    render::{cpu, gpu, Compiled, Rendered},
    scene::obj,
    settings::{camera::Camera, RenderSettings},
};
use shared::glam::DVec3;
use std::{path::PathBuf, process::Command};

fn no_progress(_: u64, _: u64) {}

fn repo(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join(rel)
}

fn cornell(light_scale: f32) -> Compiled {
    let mut scene = obj::load_obj(&repo("scenes/cornell-box.obj")).unwrap();
    for m in &mut scene.materials {
        m.emission *= light_scale;
    }
    compile(scene, BuildSettings::default())
}

fn settings(seed: u32, spp: u32) -> RenderSettings {
    let camera = Camera {
        eye: DVec3::new(0.278, 0.273, 0.8),
        target: DVec3::new(0.278, 0.273, 0.0),
        up: DVec3::Y,
        fov_deg: 39.3076,
    };
    RenderSettings { width: 24, height: 24, spp, max_bounces: 4, seed, ..RenderSettings::with_camera(camera) }
}

#[test]
fn cpu_and_gpu_agree_pixel_by_pixel_under_a_t_test() {
    let g = gpu::Gpu::open(None).expect("a Vulkan adapter (lavapipe in CI)");
    let c = cornell(1.0);
    let a = cpu::render(&c, &settings(1, 256), &no_progress).unwrap();
    let b = g.render(&c, &settings(2, 256), &no_progress).unwrap();
    let t = two_image_test(&a.stats().unwrap(), &b.stats().unwrap(), 0.01).unwrap();
    eprintln!(
        "CPU seed 1 vs {} seed 2: {} of {} channel values rejected, smallest p {:.2e} (level {:.2e})",
        g.adapter.name, t.rejected, t.tests, t.min_p, t.per_test_alpha
    );
    assert!(t.pass, "{t:?}");
    assert!(t.tests >= 24 * 24 * 3 * 9 / 10, "too few pixels could be tested: {}", t.tests);
    // The test has power: a light 10% brighter on the GPU is caught.
    let brighter = g.render(&cornell(1.1), &settings(2, 256), &no_progress).unwrap();
    let t = two_image_test(&a.stats().unwrap(), &brighter.stats().unwrap(), 0.01).unwrap();
    assert!(!t.pass, "a 10% brighter light went unnoticed: {t:?}");
}

fn same_sums(a: &Rendered, b: &Rendered) -> bool {
    a.spp == b.spp && a.sum == b.sum && a.sum_sq == b.sum_sq
}

#[test]
fn a_time_limit_stops_on_whole_samples() {
    let c = cornell(1.0);
    let limited = RenderSettings { spp: 1 << 20, time_limit_s: Some(0.3), ..settings(5, 1) };
    let r = cpu::render(&c, &limited, &no_progress).unwrap();
    assert!(r.spp >= 1 && r.spp < 1 << 20, "CPU reached {} spp", r.spp);
    assert!(
        same_sums(&r, &cpu::render(&c, &settings(5, r.spp), &no_progress).unwrap()),
        "CPU: the time-limited image is not the {}-spp image",
        r.spp
    );
    let g = gpu::Gpu::open(None).expect("a Vulkan adapter (lavapipe in CI)");
    let r = g.render(&c, &limited, &no_progress).unwrap();
    assert!(r.spp >= 1 && r.spp < 1 << 20, "GPU reached {} spp", r.spp);
    assert!(
        same_sums(&r, &g.render(&c, &settings(5, r.spp), &no_progress).unwrap()),
        "GPU: the time-limited image is not the {}-spp image",
        r.spp
    );
}

#[test]
fn render_variance_and_compare_test_a_render_against_the_mitsuba_reference() {
    let dir = std::env::temp_dir().join(format!("kdtrace-stat-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (out, var) = (dir.join("r.exr"), dir.join("v.exr"));
    let bin = env!("CARGO_BIN_EXE_kdtrace");
    let o = Command::new(bin)
        .args([
            "render",
            repo("scenes/cornell-box.obj").to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--variance",
            var.to_str().unwrap(),
        ])
        .args([
            "--width",
            "32",
            "--height",
            "32",
            "--spp",
            "1024",
            "--bounces",
            "6",
            "--seed",
            "3",
            "--eye",
            "0.278,0.273,0.8",
            "--target",
            "0.278,0.273,0",
            "--up",
            "0,1,0",
            "--fov",
            "39.3076",
            "--json",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let reference = repo("tests/data/cornell-box-mitsuba-32.exr");
    let compare = |variance: &PathBuf| {
        Command::new(bin)
            .args([
                "compare",
                reference.to_str().unwrap(),
                out.to_str().unwrap(),
                "--variance",
                variance.to_str().unwrap(),
                "--spp",
                "1024",
                "--json",
            ])
            .output()
            .unwrap()
    };
    let o = compare(&var);
    let line: serde_json::Value =
        serde_json::from_slice(&o.stdout).unwrap_or_else(|_| panic!("{}", String::from_utf8_lossy(&o.stderr)));
    eprintln!("pixel test against Mitsuba: {}", line["pixel_test"]);
    assert_eq!(line["pixel_test"]["pass"], true, "{line}");
    assert!(o.status.success());
    // A variance image claiming 1/100 of the real noise makes the same render fail: exit 1.
    let (w, h, px) = kdtrace::image::io::read_exr(&var).unwrap();
    let tight = dir.join("tight.exr");
    kdtrace::image::io::write_image(&tight, w, h, &px.iter().map(|p| p.map(|v| v / 100.0)).collect::<Vec<_>>())
        .unwrap();
    let o = compare(&tight);
    assert_eq!(o.status.code(), Some(1), "{}", String::from_utf8_lossy(&o.stdout));
}
