//! Progressive renders (`render::progressive`): passes of any split, across sample blocks or
//! inside them, add the same samples in the same order as one render (`render::blocks`), so the
//! sums equal `render`'s bit for bit, on the CPU and on lavapipe
//! (opened by name; missing lavapipe is a failure), with either GPU dispatch; `image()` between
//! passes holds the samples added so far.
#[path = "common/paths.rs"]
mod paths;
use kdtrace::{
    kdbuild::BuildSettings,
    load,
    render::{cpu, gpu, progressive::Progressive, Compiled, Rendered},
    settings::{camera::Camera, Adaptive, AdaptiveMode, Dispatch, RenderSettings},
};
use paths::mesh;
use shared::glam::DVec3;

fn no_progress(_: u64, _: u64) {}

const SPP: u32 = 20;
/// Splits of `SPP` samples into passes: passes longer than lavapipe's samples per dispatch (4),
/// which then take several dispatches, passes across the 8-sample blocks (`render::blocks`) and
/// ending inside one, and a last block that is short.
const SPLITS: [&[u32]; 3] = [&[1, 2, 5, 12], &[3, 6, 9, 2], &[20]];

fn scene() -> Compiled {
    load(&mesh("CornellBox-Sphere/CornellBox-Sphere.obj"), BuildSettings::default()).unwrap().compiled
}

fn settings() -> RenderSettings {
    let camera =
        Camera { eye: DVec3::new(0.0, 1.0, 3.4), target: DVec3::new(0.0, 1.0, 0.0), up: DVec3::Y, fov_deg: 39.3 };
    RenderSettings { width: 20, height: 16, spp: SPP, max_bounces: 4, seed: 5, ..RenderSettings::with_camera(camera) }
}

fn bits(v: &[shared::glam::Vec4]) -> Vec<[u32; 4]> {
    v.iter().map(|x| x.to_array().map(f32::to_bits)).collect()
}

fn same(a: &Rendered, b: &Rendered, what: &str) {
    assert_eq!((a.width, a.height, a.spp), (b.width, b.height, b.spp), "{what}");
    assert_eq!(bits(&a.sum), bits(&b.sum), "{what}: sums differ");
    assert_eq!(bits(&a.sum_sq), bits(&b.sum_sq), "{what}: sums of squares differ");
    assert_eq!(a.primary, b.primary, "{what}: primary hits differ");
    assert_eq!(a.traversal, b.traversal, "{what}: traversal");
    assert!(b.counts.is_none(), "{what}: a progressive image has no per-pixel counts");
}

/// Runs the passes of `split` and checks the spp of `image()` after each; the last image.
fn run(p: &mut dyn Progressive, split: &[u32], what: &str) -> Rendered {
    assert_eq!(p.image().unwrap().spp, 0, "{what}: before the first pass");
    let mut start = 0;
    let mut last = None;
    for &count in split {
        p.pass(start, count).unwrap();
        start += count;
        assert_eq!(p.spp(), start, "{what}");
        let image = p.image().unwrap();
        assert_eq!(image.spp, start, "{what}: image after samples 0..{start}");
        last = Some(image);
    }
    last.unwrap()
}

#[test]
fn cpu_passes_sum_as_one_render() {
    let (c, s) = (scene(), settings());
    let whole = cpu::render(&c, &s, &no_progress).unwrap();
    assert_eq!(whole.spp, SPP);
    let mean: f32 = whole.mean().iter().map(|p| p[0] + p[1] + p[2]).sum();
    assert!(mean > 0.0, "the image is black");
    for split in SPLITS {
        let what = format!("cpu, passes {split:?}");
        let mut p = cpu::progressive(&c, &s).unwrap();
        assert!(p.device().starts_with("cpu"));
        same(&whole, &run(&mut p, split, &what), &what);
        // Rendering on past `s.spp` is allowed: the settings' spp only sizes `render`.
        p.pass(SPP, 2).unwrap();
        assert_eq!(p.image().unwrap().spp, SPP + 2);
        assert_eq!(p.into_image().unwrap().spp, SPP + 2);
    }
}

/// The lane integrator fills its sixteen lanes from two blocks of eight where a pass holds two
/// whole ones (`RunningSums::add_two_blocks`) and splits the lanes' sums by block: the same bits
/// as passes that never hold two (every split below cuts them), on a scene it covers.
#[test]
fn cpu_lane_passes_across_two_blocks_sum_as_single_blocks() {
    let c = load(&mesh("CornellBox-Original/CornellBox-Original.obj"), BuildSettings::default()).unwrap().compiled;
    let s = RenderSettings { spp: 40, ..settings() };
    let s_cpu = RenderSettings { traversal: s.traversal.resolve(true), ..s };
    assert!(cpu::runs_lanes(&s_cpu), "the scene must run the lane integrator");
    let whole = cpu::render(&c, &s, &no_progress).unwrap();
    let mean: f32 = whole.mean().iter().map(|p| p[0] + p[1] + p[2]).sum();
    assert!(mean > 0.0, "the image is black");
    // Passes of at most one block's worth, or straddling block boundaries: none holds two whole
    // blocks from a boundary.
    for split in [&[8, 8, 8, 8, 8][..], &[4, 12, 12, 12], &[15, 15, 10]] {
        let what = format!("cpu lanes, passes {split:?}");
        let mut p = cpu::progressive(&c, &s).unwrap();
        same(&whole, &run(&mut p, split, &what), &what);
    }
    // And a pass of two blocks after a partial one: blocks 1 and 2 together.
    let mut p = cpu::progressive(&c, &s).unwrap();
    same(&whole, &run(&mut p, &[8, 16, 16], "cpu lanes, passes [8, 16, 16]"), "cpu lanes, passes [8, 16, 16]");
}

#[test]
fn lavapipe_passes_sum_as_one_render_and_as_the_cpu() {
    let (c, s) = (scene(), settings());
    let cpu_whole = cpu::render(&c, &s, &no_progress).unwrap();
    let g = gpu::Gpu::lavapipe().unwrap_or_else(|e| panic!("{e:#}"));
    for dispatch in [Dispatch::Plain, Dispatch::Persistent] {
        let s = RenderSettings { dispatch, ..s };
        let whole = g.render(&c, &s, &no_progress).unwrap();
        assert_eq!(whole.spp, SPP);
        // On lavapipe the GPU's image is the CPU's bit for bit.
        assert_eq!(bits(&whole.sum), bits(&cpu_whole.sum), "{dispatch:?}: lavapipe differs from the CPU");
        for split in SPLITS {
            let what = format!("lavapipe {dispatch:?}, passes {split:?}");
            let mut p = g.progressive(&c, &s).unwrap();
            assert_eq!(p.device(), g.adapter.name);
            same(&whole, &run(&mut p, split, &what), &what);
        }
    }
}

#[test]
fn passes_must_follow_each_other() {
    let (c, s) = (scene(), settings());
    let mut p = cpu::progressive(&c, &s).unwrap();
    assert!(p.pass(1, 1).is_err(), "a first pass must start at sample 0");
    p.pass(0, 0).unwrap();
    p.pass(0, 2).unwrap();
    assert!(p.pass(1, 1).is_err(), "samples 1..2 are in already");
    assert!(p.pass(3, 1).is_err(), "sample 2 would be missing");
    p.pass(2, 1).unwrap();
    assert_eq!(p.spp(), 3);
    assert!(p.pass(3, u32::MAX).is_err(), "past the most samples per pixel");
    let adaptive =
        RenderSettings { adaptive: Some(Adaptive { threshold: 0.05, min_spp: 4, mode: AdaptiveMode::Pilot }), ..s };
    assert!(cpu::progressive(&c, &adaptive).is_err(), "adaptive settings are refused");
}
