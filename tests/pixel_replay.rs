//! The pixel debugger's replay (`kdtrace::debug::replay`, `kdtrace pixel`): one sample of one
//! pixel run again on the CPU through the renderer's integrator with a recorder.
//!
//! - Exact: sample 0's radiance equals, bit for bit, the pixel of `kdtrace render --spp 1` on the
//!   CPU, for every pixel of a Cornell box with diffuse, textured, rough gold and smooth glass
//!   surfaces under a grey sky; sample S > 0 equals what the CPU renderer's variant and the
//!   generic `shared::integrator::render_samples` add for the sample range [S, S + 1).
//! - Consistent: at most bounces + 2 vertices, the first projects into its pixel, throughputs are
//!   the products of the BSDF weights (over roulette's survival), the radiance is the sum of what
//!   the record says was added (connections to light subpaths included), traversals start at the
//!   root and test the triangle they hit.
//! - The CLI prints one JSON line and refuses a pixel outside the image with exit code 2.
#[path = "common/paths.rs"]
mod paths;

use kdtrace::debug::{self, PathRecord};
use kdtrace::image::io::read_exr;
use kdtrace::kdbuild::BuildSettings;
use kdtrace::render::{cpu, features, Compiled};
use kdtrace::settings::{Connect, RenderSettings, SceneSettings, Traversal};
use kdtrace::{load, Loaded};
use paths::repo;
use shared::features::{Variant, FEATURES_ALL};
use shared::glam::{Vec3, Vec4};
use shared::integrator::{render_samples, PixelSpan};
use shared::layout::{RenderParams, NO_HIT};
use shared::scene::SceneView;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const SIZE: u32 = 32;
const SEED: u32 = 7;
const BOUNCES: u32 = 8;

/// A folder of this test's own (the tests run in parallel and each writes its scene file).
fn temp_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("kdtrace-pixel-replay-{}-{test}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The textured Cornell box (a poster on the back wall) with its red wall rough gold and its
/// green wall smooth glass, under a grey sky that the glass lets in: every kind of event a path
/// records (delta and sampled lights, blocked shadow rays, escapes, roulette past bounce 5).
fn mixed_scene(dir: &Path) -> PathBuf {
    let obj = repo("tests/data/cornell-textured/cornell-textured.obj").canonicalize().unwrap();
    let toml = format!(
        r#"environment = [0.2, 0.2, 0.25]

[camera]
eye = [0.278, 0.273, 0.8]
target = [0.278, 0.273, 0.0]
up = [0, 1, 0]
fov = 39.3076

[render]
bounces = {BOUNCES}
seed = {SEED}

[materials.gold]
type = "conductor"
metal = "Au"
alpha = 0.2

[materials.glass]
type = "dielectric"
ior = 1.5

[[mesh]]
file = "{}"
materials = {{ red = "gold", green = "glass" }}
"#,
        obj.display()
    );
    let path = dir.join("mixed.toml");
    std::fs::write(&path, toml).unwrap();
    path
}

/// The scene as `kdtrace render` loads it on the CPU, and its settings at `SIZE`², 1 spp.
fn loaded(scene: &Path) -> (Loaded, RenderSettings) {
    let loaded = load(scene, BuildSettings::default()).unwrap();
    let flags = SceneSettings { width: Some(SIZE), height: Some(SIZE), spp: Some(1), ..Default::default() };
    let (lo, hi) = loaded.compiled.world_bounds();
    let s = loaded.settings.overridden_by(&flags).resolve(lo, hi).unwrap();
    assert_eq!((s.seed, s.max_bounces, s.spp), (SEED, BOUNCES, 1));
    (loaded, s)
}

fn kdtrace(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kdtrace")).args(args).output().expect("run kdtrace")
}

fn bits(c: [f32; 3]) -> [u32; 3] {
    c.map(f32::to_bits)
}

#[test]
fn sample_zero_replays_the_rendered_pixel_bit_for_bit() {
    let dir = temp_dir("sample_zero_replays_the_rendered_pixel_bit_for_bit");
    let scene = mixed_scene(&dir);
    let exr = dir.join("render.exr");
    let size = SIZE.to_string();
    let o = kdtrace(&[
        "render",
        scene.to_str().unwrap(),
        "--out",
        exr.to_str().unwrap(),
        "--spp",
        "1",
        "--seed",
        &SEED.to_string(),
        "--width",
        &size,
        "--height",
        &size,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (w, h, pixels) = read_exr(&exr).unwrap();
    assert_eq!((w, h), (SIZE, SIZE));
    let (loaded, s) = loaded(&scene);
    let c = &loaded.compiled;
    let mut lit = 0;
    for y in 0..SIZE {
        for x in 0..SIZE {
            let r = debug::replay(c, &s, x, y, 0).unwrap();
            let rendered = pixels[(y * SIZE + x) as usize];
            assert_eq!(
                bits(r.radiance),
                bits(rendered),
                "pixel ({x}, {y}): replay {:?}, render {rendered:?}",
                r.radiance
            );
            lit += (r.radiance.iter().sum::<f32>() > 0.0) as u32;
        }
    }
    assert!(lit > SIZE * SIZE / 2, "only {lit} pixels lit");

    // The CLI's replay prints the same value: one JSON line, floats read back exactly.
    for (x, y) in [(3, 5), (16, 16), (31, 0), (9, 27)] {
        let o = kdtrace(&[
            "pixel",
            scene.to_str().unwrap(),
            "--x",
            &x.to_string(),
            "--y",
            &y.to_string(),
            "--width",
            &size,
            "--height",
            &size,
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let json: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON line");
        let radiance: Vec<f32> =
            json["radiance"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap() as f32).collect();
        assert_eq!(bits([radiance[0], radiance[1], radiance[2]]), bits(pixels[(y * SIZE + x) as usize]), "({x}, {y})");
        for key in ["x", "y", "sample", "zeroed", "end", "vertices", "escaped", "camera_origin"] {
            assert!(json.get(key).is_some(), "no {key}: {json}");
        }
        // The camera ray of a corner pixel may see nothing: the keys of a vertex where there is one.
        let Some(v) = json["vertices"].as_array().unwrap().first() else { continue };
        for key in [
            "position",
            "pixel",
            "t",
            "triangle",
            "material",
            "material_kind",
            "geometric_normal",
            "shading_normal",
            "front",
            "light",
            "bsdf",
            "throughput",
            "roulette",
            "nodes_visited",
            "triangles_tested",
            "truncated",
        ] {
            assert!(v.get(key).is_some(), "vertex without {key}: {v}");
        }
    }
}

#[test]
fn later_samples_replay_what_the_renderer_adds() {
    let dir = temp_dir("later_samples_replay_what_the_renderer_adds");
    let (loaded, s) = loaded(&mixed_scene(&dir));
    let c = &loaded.compiled;
    // The CPU renderer's own monomorph for the scene, and the generic code.
    let s_cpu = RenderSettings { traversal: s.traversal.resolve(true), ..s };
    let variant = cpu::variant(features::variant_bits(c, &s_cpu));
    let mut checked = 0;
    for sample in [1, 2, 5, 13, 100] {
        let params = c.params(&s_cpu, sample, 1).unwrap();
        let view = c.view(&params);
        for y in (0..SIZE).step_by(3) {
            for x in (0..SIZE).step_by(3) {
                let r = debug::replay(c, &s, x, y, sample).unwrap();
                let (sum, generic) = renderers_add(variant, &view, &params, x, y, sample);
                assert_eq!(bits(r.radiance), bits(sum.truncate().to_array()), "({x}, {y}) sample {sample}");
                assert_eq!(r.zeroed, sum.w == 1.0);
                assert_eq!(
                    bits(r.radiance),
                    bits(generic.truncate().to_array()),
                    "({x}, {y}) sample {sample}, generic"
                );
                checked += 1;
            }
        }
    }
    assert!(checked >= 200, "{checked}");
}

/// The uneven-noise room, whose paths connect to light subpaths, drawn from the pool (the
/// default) or each sample's own (`--light-pool off`, whose ray the integrator traces through the
/// path's own query before the camera ray): the records name each connection and what it added,
/// the recorder hears only the path's rays (each traversal starts at the root and tests what it
/// hit), and the replays equal what the renderer's variant and the generic code add.
#[test]
fn connections_are_recorded_and_light_subpaths_stay_out_of_the_record() {
    let loaded = load(&repo("scenes/uneven-noise.toml"), BuildSettings::default()).unwrap();
    let c = &loaded.compiled;
    let (lo, hi) = c.world_bounds();
    let s = loaded.settings.resolve(lo, hi).unwrap();
    for light_pool in [false, true] {
        let s = RenderSettings {
            width: SIZE,
            height: SIZE,
            spp: 1,
            max_bounces: BOUNCES,
            connect: Connect::On,
            light_pool,
            ..s
        };
        assert!(features::analyse(c, &s).connect, "the room connects");
        let s_cpu = RenderSettings { traversal: s.traversal.resolve(true), ..s };
        let variant = cpu::variant(features::variant_bits(c, &s_cpu));
        let (mut checked, mut lit) = (0, 0);
        let mut statuses = std::collections::BTreeSet::new();
        for sample in [0, 7] {
            let params = c.params(&s_cpu, sample, 1).unwrap();
            assert_eq!((params.connect, params.light_pool), (1, light_pool as u32));
            let view = c.view(&params);
            let (pool, first) = kdtrace::render::light_pool::pool_of(&view, &params, sample, sample + 1);
            let view = kdtrace::render::light_pool::view(&view, &pool, first);
            for y in (0..SIZE).step_by(2) {
                for x in (0..SIZE).step_by(2) {
                    let at = format!("pool {light_pool}, ({x}, {y}) sample {sample}");
                    let r = debug::replay(c, &s, x, y, sample).unwrap();
                    check_record(c, &r);
                    let (sum, generic) = renderers_add(variant, &view, &params, x, y, sample);
                    assert_eq!(bits(r.radiance), bits(sum.truncate().to_array()), "{at}");
                    assert_eq!(bits(r.radiance), bits(generic.truncate().to_array()), "{at}, generic");
                    checked += 1;
                    lit += (r.radiance.iter().sum::<f32>() > 0.0) as u32;
                    for v in &r.vertices {
                        if let Some(k) = &v.connection {
                            statuses.insert(k.status);
                        }
                    }
                }
            }
        }
        assert!(checked == 2 * 16 * 16 && lit > checked / 4, "pool {light_pool}: {lit} of {checked} lit");
        // Light reaches the room around the partition through the connections: each kind is seen.
        let statuses: Vec<_> = statuses.into_iter().collect();
        assert_eq!(statuses, ["blocked", "invalid", "unblocked"], "pool {light_pool}");
    }
}

/// What the CPU renderer's `variant` and the generic `shared::integrator::render_samples` add
/// to pixel (x, y)'s sums for the sample range [sample, sample + 1) (the fourth channel: 1 where
/// the sample was zeroed).
fn renderers_add(
    variant: cpu::VariantFn,
    view: &SceneView,
    params: &RenderParams,
    x: u32,
    y: u32,
    sample: u32,
) -> (Vec4, Vec4) {
    let (mut sum, mut sum_sq, mut primary) = (Vec4::ZERO, Vec4::ZERO, NO_HIT);
    let (sums, sums_sq) = (core::slice::from_mut(&mut sum), core::slice::from_mut(&mut sum_sq));
    let span = [PixelSpan { x, start: sample, count: 1 }];
    variant(view, params, y, &span, 1, 1, sums, sums_sq, core::slice::from_mut(&mut primary));
    let generic = Variant::new(FEATURES_ALL, params);
    let (mut generic_sum, mut sum_sq) = (Vec4::ZERO, Vec4::ZERO);
    render_samples(view, params, generic, x, y, sample, 1, &mut generic_sum, &mut sum_sq, &mut primary);
    (sum, generic_sum)
}

/// Checks one record's inner consistency; returns nothing, panics with the pixel on failure.
fn check_record(c: &Compiled, r: &PathRecord) {
    let at = format!("pixel ({}, {}) sample {}", r.x, r.y, r.sample);
    assert!(r.vertices.len() as u32 <= BOUNCES + 2, "{at}: {} vertices", r.vertices.len());
    if let Some(first) = r.vertices.first() {
        let [px, py] = first.pixel.unwrap_or_else(|| panic!("{at}: the first vertex is behind the camera"));
        let slack = 1e-3;
        assert!(
            (px >= r.x as f64 - slack)
                && (px < r.x as f64 + 1.0 + slack)
                && (py >= r.y as f64 - slack)
                && (py < r.y as f64 + 1.0 + slack),
            "{at}: first vertex projects to ({px}, {py})"
        );
    }
    // Throughput: the product of the BSDF weights, each divided by roulette's survival.
    let mut beta = Vec3::ONE;
    // Radiance: the sum, in the integrator's order, of what each event added.
    let mut sum = Vec3::ZERO;
    for (i, v) in r.vertices.iter().enumerate() {
        assert_eq!(v.bounce as usize, i, "{at}");
        let t = &v.traversal;
        assert!(!t.nodes_visited.is_empty(), "{at}: vertex {i} without nodes");
        assert_eq!(t.nodes_visited[0], 0, "{at}: vertex {i}'s traversal does not start at the root");
        assert_eq!(t.nodes_visited.len() as u32, t.nodes, "{at}");
        assert_eq!(t.triangles_tested.len() as u32, t.tests, "{at}");
        assert!(t.triangles_tested.contains(&v.triangle), "{at}: vertex {i}'s triangle was never tested");
        assert!(!t.truncated, "{at}");
        assert_eq!(c.scene.info[v.triangle as usize].material, v.material, "{at}");
        assert_eq!(v.material_kind, debug::material_kind_name(c.scene.materials[v.material as usize].kind), "{at}");
        let n = Vec3::from(v.shading_normal);
        assert!((n.length() - 1.0).abs() < 1e-4, "{at}: shading normal {n}");
        if let Some(e) = &v.emission {
            sum += Vec3::from(e.added);
        }
        if let Some(l) = &v.light {
            sum += Vec3::from(l.contribution);
            match l.status {
                "unblocked" | "blocked" => {
                    let ray = l.shadow_ray.as_ref().unwrap_or_else(|| panic!("{at}: no shadow ray"));
                    assert_eq!(l.blocked, ray.occluder.is_some(), "{at}");
                    if let Some(o) = ray.occluder {
                        assert!(ray.traversal.triangles_tested.contains(&o), "{at}: occluder never tested");
                        assert_eq!(Vec3::from(l.contribution), Vec3::ZERO, "{at}");
                    }
                    if !ray.traversal.nodes_visited.is_empty() {
                        assert_eq!(ray.traversal.nodes_visited[0], 0, "{at}");
                    }
                    assert!(l.light_pdf > 0.0 && l.mis_weight > 0.0 && l.mis_weight <= 1.0, "{at}: {l:?}");
                }
                "invalid" | "delta" => assert!(l.shadow_ray.is_none(), "{at}"),
                other => panic!("{at}: light status {other}"),
            }
            if l.status == "delta" {
                assert!(matches!(v.material_kind, "conductor" | "dielectric"), "{at}: {}", v.material_kind);
            }
        }
        if let Some(k) = &v.connection {
            sum += Vec3::from(k.contribution);
            let ray = k.shadow_ray.as_ref();
            match k.status {
                "unblocked" | "blocked" => {
                    let ray = ray.unwrap_or_else(|| panic!("{at}: a connection without its shadow ray"));
                    assert_eq!(k.status == "blocked", ray.occluder.is_some(), "{at}");
                    assert_eq!(ray.traversal.nodes_visited.first(), Some(&0), "{at}: the connection's traversal");
                    if let Some(o) = ray.occluder {
                        assert!(ray.traversal.triangles_tested.contains(&o), "{at}: occluder never tested");
                        assert_eq!(Vec3::from(k.contribution), Vec3::ZERO, "{at}");
                    }
                    assert!(k.point.is_some(), "{at}");
                }
                "invalid" => assert!(ray.is_none() && Vec3::from(k.contribution) == Vec3::ZERO, "{at}"),
                other => panic!("{at}: connection status {other}"),
            }
        }
        let before = beta;
        if let Some(b) = &v.bsdf {
            if b.valid {
                beta *= Vec3::from(b.weight);
            }
        }
        if let Some(rr) = &v.roulette {
            assert!(rr.survived == (rr.uniform < rr.survival), "{at}");
            if rr.survived {
                beta /= rr.survival;
            }
        }
        assert_eq!(bits(v.throughput), bits(beta.to_array()), "{at}: vertex {i}'s throughput (before: {before})");
        let last = i + 1 == r.vertices.len();
        if !last {
            // The next ray leaves along this vertex's sample.
            assert_eq!(r.vertices[i + 1].ray_direction, v.bsdf.as_ref().unwrap().wi, "{at}");
        }
    }
    if let Some(e) = &r.escaped {
        sum += Vec3::from(e.environment);
        assert_eq!(e.bounce as usize, r.vertices.len(), "{at}");
        assert_eq!(r.end, "escaped", "{at}");
    }
    assert_eq!(
        bits(sum.to_array()),
        bits(r.raw_radiance),
        "{at}: the events add up to {sum}, the path to {:?}",
        r.raw_radiance
    );
}

#[test]
fn records_are_consistent() {
    let dir = temp_dir("records_are_consistent");
    let (loaded, s) = loaded(&mixed_scene(&dir));
    let c = &loaded.compiled;
    let mut kinds = std::collections::BTreeSet::new();
    let mut statuses = std::collections::BTreeSet::new();
    let mut ends = std::collections::BTreeSet::new();
    let (mut roulette, mut poster, mut escapes, mut deep) = (0, 0, 0, 0);
    let poster_material =
        c.scene.material_names.iter().position(|n| n.contains("poster")).expect("the poster material");
    for sample in [0, 3] {
        for y in 0..SIZE {
            for x in 0..SIZE {
                let r = debug::replay(c, &s, x, y, sample).unwrap();
                check_record(c, &r);
                ends.insert(r.end);
                escapes += r.escaped.is_some() as u32;
                deep = deep.max(r.vertices.len());
                for v in &r.vertices {
                    kinds.insert(v.material_kind);
                    poster += (v.material as usize == poster_material) as u32;
                    roulette += v.roulette.is_some() as u32;
                    if let Some(l) = &v.light {
                        statuses.insert(l.status);
                    }
                }
            }
        }
    }
    for kind in ["diffuse", "conductor", "dielectric"] {
        assert!(kinds.contains(kind), "no {kind} vertex: {kinds:?}");
    }
    for status in ["unblocked", "blocked", "delta"] {
        assert!(statuses.contains(status), "no {status} light sample: {statuses:?}");
    }
    assert!(ends.contains("escaped") && ends.contains("bounce_limit"), "{ends:?}");
    assert!(roulette > 0 && poster > 0 && escapes > 0, "roulette {roulette}, poster {poster}, escapes {escapes}");
    assert!(deep > 2, "the deepest path has {deep} vertices");

    // The short stack restarts, but finds the same hits: the same radiance, and a record as
    // consistent, whose traversals start at the root.
    let short = RenderSettings { traversal: Traversal::Short, ..s };
    for (x, y) in [(0, 0), (5, 17), (16, 16), (30, 2), (12, 31)] {
        let a = debug::replay(c, &s, x, y, 1).unwrap();
        let b = debug::replay(c, &short, x, y, 1).unwrap();
        assert_eq!(bits(a.radiance), bits(b.radiance), "({x}, {y})");
        check_record(c, &b);
    }
}

#[test]
fn a_pixel_outside_the_image_is_an_error() {
    let dir = temp_dir("a_pixel_outside_the_image_is_an_error");
    let scene = mixed_scene(&dir);
    let (loaded, s) = loaded(&scene);
    let c = &loaded.compiled;
    assert!(debug::replay(c, &s, SIZE, 0, 0).is_err());
    let e = debug::replay(c, &s, 0, SIZE + 5, 0).unwrap_err();
    assert!(format!("{e:#}").contains("outside"), "{e:#}");
    let size = SIZE.to_string();
    let o = kdtrace(&["pixel", scene.to_str().unwrap(), "--x", &size, "--y", "0", "--width", &size, "--height", &size]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("outside") && err.contains(&format!("({SIZE}, 0)")), "{err}");
    assert!(o.stdout.is_empty());
    let o = kdtrace(&["pixel", scene.to_str().unwrap(), "--x", "-1", "--y", "0"]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    let o = kdtrace(&["pixel", dir.join("missing.obj").to_str().unwrap(), "--x", "0", "--y", "0"]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn projection_inverts_the_camera_ray() {
    let dir = temp_dir("projection_inverts_the_camera_ray");
    let (_, s) = loaded(&mixed_scene(&dir));
    let (right, up, forward) = s.camera.basis(s.aspect()).unwrap();
    for (fx, fy) in [(0.5, 0.5), (0.0, 0.0), (31.25, 7.75), (16.0, 31.999)] {
        let sx = 2.0 * fx / SIZE as f64 - 1.0;
        let sy = 1.0 - 2.0 * fy / SIZE as f64;
        let d = forward.as_dvec3() + right.as_dvec3() * sx + up.as_dvec3() * sy;
        let p = s.camera.eye + d * 2.5;
        let [px, py] = debug::project(&s, p).unwrap();
        assert!((px - fx).abs() < 1e-9 && (py - fy).abs() < 1e-9, "({fx}, {fy}) → ({px}, {py})");
        assert_eq!(debug::project(&s, s.camera.eye - d), None, "behind the camera");
    }
}
