//! Survey coordinates kept exact: CornellBox-Original, centred on the origin, is written again
//! with f64 coordinates moved by 1e5 and by 1e6 on every axis and to UTM-like coordinates
//! (easting ≈ 4e5, northing ≈ 6e6), the camera moved with it. Loaded as a user loads it
//! (`kdtrace::load`: vertices and camera in f64, moved to the local frame, rounded to f32 once),
//! every moved render passes a per-pixel Welch t-test against the origin render (Šidák, α = 0.01)
//! on the CPU, and lavapipe renders each moved scene bit for bit as the CPU does. Where the
//! moved scene's local frame holds the very same f32 geometry and camera (the 1e5 and 1e6 moves,
//! whose f64 coordinates are the origin's f32 coordinates plus an integer), the image is the
//! origin's bit for bit. The same scene read in f32 world coordinates fails the t-test: the test
//! can tell.
#[path = "common/paths.rs"]
mod paths;
use kdtrace::{
    compile,
    image::metrics::{two_image_test, PixelTest},
    kdbuild::BuildSettings,
    load,
    render::{cpu, gpu, Compiled, Rendered},
    scene::{local_frame::to_local, obj},
    settings::{camera::Camera, RenderSettings},
};
use paths::mesh;
use shared::glam::DVec3;
use std::path::{Path, PathBuf};

fn no_progress(_: u64, _: u64) {}

fn tmp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("kdtrace-survey-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// CornellBox-Original's vertices, centred on the origin and rounded to f32 (so that adding an
/// integer shift is exact in f64), and the camera of `../shared/docs/peers.md` moved with them.
struct Origin {
    text: String,
    centre: DVec3,
}

fn origin_scene() -> Origin {
    let text = std::fs::read_to_string(mesh("CornellBox-Original/CornellBox-Original.obj")).unwrap();
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for v in text.lines().filter_map(vertex) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    Origin { centre: 0.5 * (lo + hi), text }
}

/// The point a `v x y z` line states, or `None` for any other line.
fn vertex(line: &str) -> Option<DVec3> {
    let mut w = line.split_whitespace();
    (w.next() == Some("v")).then(|| {
        let c: Vec<f64> = w.take(3).map(|x| x.parse().unwrap()).collect();
        DVec3::new(c[0], c[1], c[2])
    })
}

/// `p` centred and rounded to f32, as an f64.
fn centred(p: DVec3, centre: DVec3) -> DVec3 {
    (p - centre).as_vec3().as_dvec3()
}

/// Writes the box moved by `shift` (f64 coordinates, shortest round-trip form) with its MTL.
fn write_moved(o: &Origin, shift: DVec3, dir: &Path) -> PathBuf {
    let mut out = String::new();
    for line in o.text.lines() {
        if let Some(v) = vertex(line) {
            let p = centred(v, o.centre) + shift;
            out.push_str(&format!("v {:?} {:?} {:?}\n", p.x, p.y, p.z));
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    let path = dir.join("CornellBox-Original.obj");
    std::fs::write(&path, out).unwrap();
    std::fs::copy(mesh("CornellBox-Original/CornellBox-Original.mtl"), dir.join("CornellBox-Original.mtl")).unwrap();
    path
}

fn settings(o: &Origin, shift: DVec3, seed: u32) -> RenderSettings {
    let camera = Camera {
        eye: centred(DVec3::new(0.0, 1.0, 3.4), o.centre) + shift,
        target: centred(DVec3::new(0.0, 1.0, 0.0), o.centre) + shift,
        up: DVec3::Y,
        fov_deg: 39.3,
    };
    RenderSettings { width: 48, height: 48, spp: 64, max_bounces: 4, seed, ..RenderSettings::with_camera(camera) }
}

fn t_test(a: &Rendered, b: &Rendered) -> PixelTest {
    two_image_test(&a.stats().unwrap(), &b.stats().unwrap(), 0.01).unwrap()
}

fn same_bits(a: &Rendered, b: &Rendered) -> bool {
    a.sum.iter().zip(&b.sum).all(|(x, y)| x.to_array().map(f32::to_bits) == y.to_array().map(f32::to_bits))
        && a.primary == b.primary
}

fn geometry_bits(c: &Compiled) -> Vec<u32> {
    c.scene.triangles.iter().flat_map(|t| [t.v0, t.v1, t.v2]).flat_map(|v| v.to_array().map(f32::to_bits)).collect()
}

fn params_bits(c: &Compiled, s: &RenderSettings) -> Vec<u8> {
    bytemuck::bytes_of(&c.params(s, 0, 1).unwrap()).to_vec()
}

#[test]
fn moved_boxes_render_like_the_box_at_the_origin_on_cpu_and_lavapipe() {
    let o = origin_scene();
    let origin_path = write_moved(&o, DVec3::ZERO, &tmp_dir("origin"));
    let at_origin = load(&origin_path, BuildSettings::default()).unwrap().compiled;
    assert_eq!(at_origin.origin, DVec3::ZERO, "the centred box straddles every axis: no move");
    let reference = cpu::render(&at_origin, &settings(&o, DVec3::ZERO, 1), &no_progress).unwrap();
    let lit = reference.mean().iter().filter(|p| p[0] + p[1] + p[2] > 0.05).count();
    assert!(lit > 48 * 48 / 2, "the camera should see the lit box: {lit} lit pixels");
    let g = gpu::Gpu::lavapipe().unwrap_or_else(|e| panic!("{e:#}"));
    let cases = [
        ("1e5", DVec3::splat(1e5), true),
        ("1e6", DVec3::splat(1e6), true),
        ("UTM", DVec3::new(412_345.67, 31.25, 6_123_456.78), false),
    ];
    for (name, shift, exact) in cases {
        let path = write_moved(&o, shift, &tmp_dir(name));
        let moved = load(&path, BuildSettings::default()).unwrap().compiled;
        assert!((moved.origin - shift).abs().max_element() < 1.0, "{name}: local frame at {}", moved.origin);
        // Same f32 geometry and camera in the local frame: the same image, bit for bit.
        let same_frame = geometry_bits(&moved) == geometry_bits(&at_origin)
            && params_bits(&moved, &settings(&o, shift, 1)) == params_bits(&at_origin, &settings(&o, DVec3::ZERO, 1));
        assert_eq!(
            same_frame,
            exact,
            "{name}: the local frame should {}hold the origin's geometry",
            ["not ", ""][exact as usize]
        );
        if same_frame {
            let img = cpu::render(&moved, &settings(&o, shift, 1), &no_progress).unwrap();
            assert!(same_bits(&reference, &img), "{name}: same local geometry and camera, different image");
        }
        let s = settings(&o, shift, 2);
        let img = cpu::render(&moved, &s, &no_progress).unwrap();
        let t = t_test(&reference, &img);
        eprintln!(
            "{name}: origin {}, t-test {} of {} rejected, min p {:.3e}",
            moved.origin, t.rejected, t.tests, t.min_p
        );
        assert!(t.pass, "{name}: the moved box renders differently from the box at the origin: {t:?}");
        assert!(t.tests > 48 * 48 * 3 / 2, "{name}: too few pixels tested ({})", t.tests);
        let on_gpu = g.render(&moved, &s, &no_progress).unwrap();
        assert!(same_bits(&img, &on_gpu), "{name}: lavapipe's image differs from the CPU's");
    }
}

/// The control: the 1e6 box read as f32 world coordinates (each vertex rounded to 1/16 before
/// the exact move home, as before coordinates were kept in f64) fails the same test. (At 1e5
/// the 1/128 steps stay within a pixel of this 48×48 image: the test sees them at larger sizes.)
#[test]
fn f32_world_coordinates_fail_the_same_test() {
    let o = origin_scene();
    let origin_path = write_moved(&o, DVec3::ZERO, &tmp_dir("control-origin"));
    let at_origin = load(&origin_path, BuildSettings::default()).unwrap().compiled;
    let reference = cpu::render(&at_origin, &settings(&o, DVec3::ZERO, 1), &no_progress).unwrap();
    let shift = DVec3::splat(1e6);
    let path = write_moved(&o, shift, &tmp_dir("control-1e6"));
    let (scene, origin) = to_local(obj::load_obj(&path).unwrap());
    let mut rounded = compile(scene, BuildSettings::default());
    rounded.origin = origin;
    let img = cpu::render(&rounded, &settings(&o, shift, 2), &no_progress).unwrap();
    let t = t_test(&reference, &img);
    eprintln!("f32 world coordinates at 1e6: t-test {} of {} rejected, min p {:.3e}", t.rejected, t.tests, t.min_p);
    assert!(!t.pass, "rounding vertices to 1/16 should move the box's edges visibly: {t:?}");
}
