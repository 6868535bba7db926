//! Whole renders under numerical stress: the Cornell box scaled by 1e-4 and 1e4 and moved 1e5
//! away renders like the plain one within noise on both devices with no non-finite sample, and
//! coincident duplicate faces (CornellBox-Original stores each box's front twice) render like the
//! deduplicated scene. Garbage rays are misses on every traversal.
use kdtrace::camera::Camera;
use kdtrace::kdbuild::BuildSettings;
use kdtrace::render::{Compiled, RenderSettings, Rendered, Traversal};
use kdtrace::scene::Scene;
use kdtrace::transform::Placement;
use kdtrace::verify::compare;
use kdtrace::{compile, cpu, gpu, obj};
use shared::glam::Vec3;
use shared::layout::{RayQuery, RAY_ANY_HIT, RAY_SHORT_STACK, TRAVERSAL_FULL_STACK, TRAVERSAL_SHORT_STACK};
use shared::raycast::{any, cast_ray, closest};
use std::collections::HashSet;
use std::path::PathBuf;

fn no_progress(_: u64, _: u64) {}

fn repo(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join(rel)
}

/// The scene with every vertex scaled by `scale` and moved by `shift` on each axis.
fn placed(scene: &Scene, scale: f32, shift: f32) -> Compiled {
    let mut tris = scene.triangles.clone();
    Placement { scale: Vec3::splat(scale), translate: Vec3::splat(shift), ..Default::default() }.apply(&mut tris);
    let material_of = scene.info.iter().map(|i| i.material).collect();
    let s = Scene::new(tris, material_of, scene.materials.clone(), scene.material_names.clone()).unwrap();
    assert_eq!(s.triangles.len(), scene.triangles.len(), "scale {scale}, shift {shift}: triangles collapsed");
    compile(s, BuildSettings::default())
}

fn settings(scale: f32, shift: f32, seed: u32) -> RenderSettings {
    let p = |v: Vec3| v * scale + Vec3::splat(shift);
    let camera = Camera { eye: p(Vec3::new(0.278, 0.273, 0.8)), target: p(Vec3::new(0.278, 0.273, -0.2796)), up: Vec3::Y, fov_deg: 39.3076 };
    RenderSettings { width: 48, height: 48, spp: 64, max_bounces: 4, seed, ..RenderSettings::with_camera(camera) }
}

const BLOCK: u32 = 8;

/// Mean radiance of each 8×8 block, per channel.
fn blocks(r: &Rendered) -> Vec<f64> {
    let m = r.mean();
    let mut out = Vec::new();
    for by in 0..r.height / BLOCK {
        for bx in 0..r.width / BLOCK {
            for k in 0..3 {
                let mut sum = 0.0f64;
                for y in by * BLOCK..(by + 1) * BLOCK {
                    for x in bx * BLOCK..(bx + 1) * BLOCK {
                        sum += m[(y * r.width + x) as usize][k] as f64;
                    }
                }
                out.push(sum / (BLOCK * BLOCK) as f64);
            }
        }
    }
    out
}

/// Σ (a − b)² over the blocks, in units of the same sum between two independent renders of the
/// reference (pure noise): about 1 when `test` differs from `reference` only by noise.
fn excess(reference: &Rendered, reference_other_seed: &Rendered, test: &Rendered) -> f64 {
    let (r, r2, t) = (blocks(reference), blocks(reference_other_seed), blocks(test));
    let noise: f64 = r.iter().zip(&r2).map(|(a, b)| (a - b) * (a - b)).sum();
    let diff: f64 = r.iter().zip(&t).map(|(a, b)| (a - b) * (a - b)).sum();
    diff / noise
}

fn finite(r: &Rendered) -> bool {
    r.zeroed_samples() == 0 && r.mean().iter().all(|p| p.iter().all(|c| c.is_finite() && *c >= 0.0))
}

/// The box scaled by 1e-4 and 1e4 must render like the plain one. Moved 1e5 away, f32 itself
/// rounds every vertex and the camera to 1/128: that changes the scene, not the renderer's
/// handling of it. So the moved box is compared with its own rounded geometry and camera moved
/// back to the origin (an exact subtraction): what differs then is only the renderer at large
/// coordinates (ray offsets, intersection precision).
#[test]
fn scaled_and_moved_cornell_boxes_render_like_the_plain_one() {
    let base = obj::load_obj(&repo("scenes/cornell-box.obj")).unwrap();
    let g = gpu::Gpu::open(None).expect("a Vulkan adapter (lavapipe in CI)");
    let plain = placed(&base, 1.0, 0.0);
    let plain_ref = cpu::render(&plain, &settings(1.0, 0.0, 1), &no_progress).unwrap();
    let plain_ref2 = cpu::render(&plain, &settings(1.0, 0.0, 2), &no_progress).unwrap();
    for (scale, shift) in [(1e-4f32, 0.0f32), (1e4, 0.0), (1.0, 1e5)] {
        let c = placed(&base, scale, shift);
        let s = settings(scale, shift, 3);
        let (reference, reference2) = if shift == 0.0 {
            (plain_ref.clone(), plain_ref2.clone())
        } else {
            let back = placed(&c.scene, 1.0, -shift);
            let mut near = s;
            near.camera.eye -= Vec3::splat(shift);
            near.camera.target -= Vec3::splat(shift);
            let seeded = |seed| RenderSettings { seed, ..near };
            (cpu::render(&back, &seeded(1), &no_progress).unwrap(), cpu::render(&back, &seeded(2), &no_progress).unwrap())
        };
        let img = cpu::render(&c, &s, &no_progress).unwrap();
        let gpu_img = g.render(&c, &s, &no_progress).unwrap();
        let e = excess(&reference, &reference2, &img);
        let agreement = compare(&img, &gpu_img);
        eprintln!("scale {scale:e}, shift {shift:e}: block error {e:.2}× noise; CPU/GPU pixels within 1e-3: {}/{}", agreement.pixels_within, agreement.pixels);
        assert!(finite(&img) && finite(&gpu_img), "scale {scale:e}, shift {shift:e}: non-finite or negative samples");
        assert!(e < 3.0, "scale {scale:e}, shift {shift:e}: differs from the reference by {e:.2}× the noise");
        assert!(agreement.pass, "scale {scale:e}, shift {shift:e}: CPU and GPU disagree: {agreement:?}");
    }
    // The statistic notices a real change: a box with the light 10% dimmer fails it.
    let mut dim = base.clone();
    for m in &mut dim.materials {
        m.emission *= 0.9;
    }
    let e = excess(&plain_ref, &plain_ref2, &cpu::render(&placed(&dim, 1.0, 0.0), &settings(1.0, 0.0, 3), &no_progress).unwrap());
    assert!(e > 3.0, "a 10% dimmer light went unnoticed ({e:.2}× noise)");
}

#[test]
fn coincident_duplicate_faces_render_like_the_deduplicated_scene() {
    let path = repo("../shared/scenes/CornellBox-Original/CornellBox-Original.obj");
    assert!(path.exists(), "{} is missing", path.display());
    let with = obj::load_obj(&path).unwrap();
    let mut seen = HashSet::new();
    let (mut tris, mut mats) = (Vec::new(), Vec::new());
    for (t, info) in with.triangles.iter().zip(&with.info) {
        let mut key = [t.v0, t.v1, t.v2].map(|v| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()]);
        key.sort();
        if seen.insert((key, info.material)) {
            tris.push(*t);
            mats.push(info.material);
        }
    }
    let duplicates = with.triangles.len() - tris.len();
    assert!(duplicates >= 4, "expected the boxes' duplicated fronts, found {duplicates} duplicates");
    let without = Scene::new(tris, mats, with.materials.clone(), with.material_names.clone()).unwrap();
    let camera = Camera { eye: Vec3::new(0.0, 1.0, 3.4), target: Vec3::new(0.0, 1.0, 0.0), up: Vec3::Y, fov_deg: 39.3 };
    let s = |seed| RenderSettings { width: 48, height: 48, spp: 64, max_bounces: 4, seed, traversal: Traversal::Short, ..RenderSettings::with_camera(camera) };
    let (cw, cwo) = (compile(with, BuildSettings::default()), compile(without, BuildSettings::default()));
    let a = cpu::render(&cw, &s(1), &no_progress).unwrap();
    let a2 = cpu::render(&cw, &s(2), &no_progress).unwrap();
    let b = cpu::render(&cwo, &s(1), &no_progress).unwrap();
    let e = excess(&a, &a2, &b);
    let identical = a.sum.iter().zip(&b.sum).filter(|(x, y)| x == y).count();
    eprintln!("CornellBox-Original: {duplicates} duplicate faces; with vs without: {e:.2}× noise, {identical}/{} pixels identical", a.sum.len());
    assert!(e < 3.0, "duplicate faces change the image by {e:.2}× the noise");
}

#[test]
fn garbage_rays_are_misses_on_every_traversal() {
    let c = placed(&obj::load_obj(&repo("scenes/cornell-box.obj")).unwrap(), 1.0, 0.0);
    let params = c.bounds_params();
    let scene = c.view(&params);
    let (nan, inf) = (f32::NAN, f32::INFINITY);
    let inside = Vec3::new(0.2, 0.2, -0.2);
    let cases = [
        (Vec3::new(nan, 0.2, 0.2), Vec3::X),
        (inside, Vec3::new(nan, 1.0, 0.0)),
        (Vec3::new(inf, 0.2, -0.2), -Vec3::X),
        (inside, Vec3::new(-inf, 0.0, 0.0)),
        (inside, Vec3::ZERO),
        (inside, Vec3::new(1e-40, -1e-42, 0.0)),
        (Vec3::splat(f32::MAX), -Vec3::ONE),
    ];
    for (o, d) in cases {
        for traversal in [TRAVERSAL_FULL_STACK, TRAVERSAL_SHORT_STACK] {
            assert!(!closest(&scene, traversal, o, d, f32::MAX).hit.is_hit(), "o={o:?} d={d:?}");
            assert!(!any(&scene, traversal, o, d, f32::MAX).hit.is_hit(), "o={o:?} d={d:?}");
        }
        for flags in [0, RAY_ANY_HIT, RAY_SHORT_STACK, RAY_SHORT_STACK | RAY_ANY_HIT] {
            let q = RayQuery { origin: o.extend(0.0), dir: d.extend(0.0), t_max: f32::MAX, flags, _pad: [0; 2] };
            assert_eq!(cast_ray(&scene, &q).triangle, u32::MAX, "o={o:?} d={d:?}");
        }
    }
    // Sanity: a proper ray from the same point does hit.
    assert!(closest(&scene, TRAVERSAL_SHORT_STACK, inside, -Vec3::Y, f32::MAX).hit.is_hit());
}
