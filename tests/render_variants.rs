//! Every way of rendering gives the same image: full-stack and short-stack traversal on the CPU,
//! and on the GPU each traversal with one invocation per pixel and with persistent threads. The
//! cost AOV (camera-ray traversal work) agrees between devices too and means what it says.
#[path = "common/paths.rs"]
mod paths;
use kdtrace::{
    kdbuild::BuildSettings,
    load,
    render::{cpu, gpu, Compiled, Rendered},
    settings::{camera::Camera, Aov, Dispatch, RenderSettings, Traversal},
};
use paths::mesh;
use shared::glam::DVec3;

fn no_progress(_: u64, _: u64) {}

/// The water scene on the GPU's tree (`BuildSettings::for_gpu`): leaves of one to a few
/// triangles make it deep enough that a 4-entry short stack overflows and restarts, which the
/// CPU's shallow tree of eight-triangle leaves rarely does.
fn water() -> Compiled {
    let path = mesh("CornellBox-Water/CornellBox-Water.obj");
    assert!(path.exists(), "{} is missing", path.display());
    load(&path, BuildSettings::for_gpu()).unwrap().compiled
}

fn settings() -> RenderSettings {
    let camera =
        Camera { eye: DVec3::new(0.0, 1.0, 3.4), target: DVec3::new(0.0, 1.0, 0.0), up: DVec3::Y, fov_deg: 39.3076 };
    RenderSettings { width: 48, height: 40, spp: 8, max_bounces: 5, seed: 3, ..RenderSettings::with_camera(camera) }
}

fn same(a: &Rendered, b: &Rendered, what: &str) {
    let differ = a
        .sum
        .iter()
        .zip(&b.sum)
        .filter(|(x, y)| x.to_array().map(f32::to_bits) != y.to_array().map(f32::to_bits))
        .count();
    let primary = a.primary.iter().zip(&b.primary).filter(|(x, y)| x != y).count();
    assert_eq!((differ, primary), (0, 0), "{what}: {differ} pixels and {primary} primary hits differ");
}

#[test]
fn all_traversal_and_dispatch_variants_render_the_same_image() {
    let c = water();
    let base = settings();
    let reference = cpu::render(&c, &RenderSettings { traversal: Traversal::Full, ..base }, &no_progress).unwrap();
    let lit = reference.mean().iter().filter(|p| p[0] + p[1] + p[2] > 0.01).count();
    assert!(lit > reference.sum.len() / 2, "the scene should be mostly lit ({lit} lit pixels)");
    same(
        &reference,
        &cpu::render(&c, &RenderSettings { traversal: Traversal::Short, ..base }, &no_progress).unwrap(),
        "CPU short stack",
    );
    // `auto` takes the wide BVH on the CPU path (measured faster there): another structure,
    // the same hits.
    let auto = cpu::render(&c, &RenderSettings { traversal: Traversal::Auto, ..base }, &no_progress).unwrap();
    assert_eq!(auto.traversal, Traversal::Wide);
    same(&reference, &auto, "CPU auto (wide BVH)");
    same(
        &reference,
        &cpu::render(&c, &RenderSettings { traversal: Traversal::Wide, ..base }, &no_progress).unwrap(),
        "CPU wide BVH",
    );
    let g = gpu::Gpu::lavapipe().unwrap_or_else(|e| panic!("{e:#}"));
    let wide = g.render(&c, &RenderSettings { traversal: Traversal::Wide, ..base }, &no_progress);
    assert!(format!("{:#}", wide.unwrap_err()).contains("CPU path"), "a GPU has no wide BVH");
    for traversal in [Traversal::Full, Traversal::Short, Traversal::Auto] {
        for dispatch in [Dispatch::Plain, Dispatch::Persistent] {
            let img = g.render(&c, &RenderSettings { traversal, dispatch, ..base }, &no_progress).unwrap();
            same(&reference, &img, &format!("GPU {traversal:?} {dispatch:?} on {}", g.adapter.name));
            assert_eq!(img.traversal, traversal.resolve(g.is_cpu()), "the image reports the traversal that made it");
        }
    }
}

/// `render --device` builds a different tree per device (`BuildSettings::for_gpu`): leaves of
/// one to a few triangles for the GPU, of a dozen or more for the CPU's eight-lane test. Hits are
/// exact on any tree, so the images must still be identical, bit for bit.
#[test]
fn each_device_on_its_own_tree_renders_the_same_image() {
    let path = mesh("CornellBox-Water/CornellBox-Water.obj");
    let cpu_tree = load(&path, BuildSettings::default()).unwrap().compiled;
    let gpu_tree = load(&path, BuildSettings::for_gpu()).unwrap().compiled;
    assert!(
        gpu_tree.tree().nodes.len() > 4 * cpu_tree.tree().nodes.len(),
        "the trees should differ: {} and {} nodes",
        gpu_tree.tree().nodes.len(),
        cpu_tree.tree().nodes.len()
    );
    let s = settings();
    let reference = cpu::render(&cpu_tree, &s, &no_progress).unwrap();
    same(&reference, &cpu::render(&gpu_tree, &s, &no_progress).unwrap(), "CPU on the GPU's tree");
    let g = gpu::Gpu::lavapipe().unwrap_or_else(|e| panic!("{e:#}"));
    same(
        &reference,
        &g.render(&gpu_tree, &s, &no_progress).unwrap(),
        &format!("GPU on its own tree, {}", g.adapter.name),
    );
}

#[test]
fn cost_aov_counts_the_camera_ray_work_on_both_devices() {
    let c = water();
    let g = gpu::Gpu::lavapipe().unwrap_or_else(|e| panic!("{e:#}"));
    for traversal in [Traversal::Full, Traversal::Short] {
        let s = RenderSettings { aov: Aov::Cost, traversal, spp: 2, ..settings() };
        let a = cpu::render(&c, &s, &no_progress).unwrap();
        same(&a, &g.render(&c, &s, &no_progress).unwrap(), &format!("cost AOV, {traversal:?}"));
        let mean = a.mean();
        // Where sample 0's camera ray hit a triangle, it visited a node and tested a triangle
        // (half of the two-sample mean at least); rays that miss the scene box cost nothing.
        let hit: Vec<usize> = (0..mean.len()).filter(|&i| a.primary[i] != shared::layout::NO_HIT).collect();
        assert!(hit.len() > mean.len() / 2, "{traversal:?}: only {} camera rays hit", hit.len());
        assert!(
            hit.iter().all(|&i| mean[i][0] >= 0.5 && mean[i][1] >= 0.5),
            "{traversal:?}: a hit without traversal work"
        );
        assert!(
            mean.iter().any(|p| p[0] >= 10.0),
            "{traversal:?}: no camera ray went deeper than 10 nodes in a 7k-triangle tree"
        );
        let restarts: f32 = mean.iter().map(|p| p[2]).sum();
        match traversal {
            Traversal::Full => assert_eq!(restarts, 0.0, "the full stack never restarts"),
            Traversal::Short => assert!(restarts > 0.0, "a 4-entry stack on a 7k-triangle tree restarts somewhere"),
            Traversal::Auto | Traversal::Wide => unreachable!(),
        }
    }
}
