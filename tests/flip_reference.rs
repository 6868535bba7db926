//! ꟻLIP (`kdtrace::image::metrics::flip_srgb8`, NVIDIA's C++ through the `nv-flip` crate) against the
//! values of NVIDIA's official `flip-evaluator` 1.7 (PyPI), stored in tests/data/flip by
//! tests/data/flip/make_flip_reference.py: the mean to 1e-6 and every pixel of the error map to
//! 1e-5, for a noisy-vs-converged render and a synthetic pattern pair (edges, lines, dots,
//! colour shifts).
use kdtrace::image::{io::read_pfm, metrics::flip_srgb8};
use std::path::{Path, PathBuf};

fn data() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/data/flip")
}

fn png(path: &Path) -> (u32, u32, Vec<u8>) {
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).into_rgb8();
    (img.width(), img.height(), img.into_raw())
}

fn check_pair(name: &str) {
    let expected: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data().join("expected.json")).unwrap()).unwrap();
    let pair = &expected["pairs"][name];
    let ppd = expected["ppd"].as_f64().unwrap() as f32;
    let (w, h, r) = png(&data().join(pair["reference"].as_str().unwrap()));
    let (w2, h2, t) = png(&data().join(pair["test"].as_str().unwrap()));
    assert_eq!((w, h), (w2, h2));
    let (mean, map) = flip_srgb8(w, h, &r, &t, ppd);
    let official_mean = pair["mean"].as_f64().unwrap();
    assert!((mean - official_mean).abs() < 1e-6, "{name}: mean {mean} vs official {official_mean}");
    let (mw, mh, official) = read_pfm(&data().join(format!("{name}.flip.pfm"))).unwrap();
    assert_eq!((mw, mh), (w, h));
    let worst = map.iter().zip(&official).map(|(a, b)| (a - b[0]).abs()).fold(0f32, f32::max);
    assert!(worst < 1e-5, "{name}: largest per-pixel difference {worst}");
    // The check can fail: the map is not flat, so a shifted map would not match.
    assert!(official.iter().map(|p| p[0]).fold(0f32, f32::max) > 0.4);
}

#[test]
fn flip_matches_nvidia_flip_evaluator_on_noisy_render() {
    check_pair("cornell");
}

#[test]
fn flip_matches_nvidia_flip_evaluator_on_synthetic_patterns() {
    check_pair("pattern");
}

#[test]
fn flip_is_zero_for_equal_images_and_depends_on_pixels_per_degree() {
    // The stored values pin the viewing distance: ꟻLIP's filters scale with pixels per degree.
    let (w, h, r) = png(&data().join("pattern-ref.png"));
    let (_, _, t) = png(&data().join("pattern-test.png"));
    assert_eq!(flip_srgb8(w, h, &r, &r, 67.0).0, 0.0);
    let (near, far) = (flip_srgb8(w, h, &r, &t, 30.0).0, flip_srgb8(w, h, &r, &t, 67.0).0);
    assert!((near - far).abs() > 1e-3, "{near} {far}");
}
