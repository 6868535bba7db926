//! `kdtrace compare` as a user meets it: EXR and PFM in, one JSON line with every metric, NaN/Inf
//! counts, and exit code 2 naming both files for images of different sizes (and for bad files).
use kdtrace::image::io::{write_image, write_pfm};
use std::{
    path::PathBuf,
    process::{Command, Output},
};

fn kdtrace(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kdtrace")).args(args).output().expect("run kdtrace")
}

fn tmp(name: &str) -> String {
    let dir = std::env::temp_dir().join(format!("kdtrace-compare-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name).to_string_lossy().into_owned()
}

fn gradient(w: u32, h: u32, scale: f32) -> Vec<[f32; 3]> {
    (0..w * h).map(|i| [scale * (i % w) as f32 / w as f32, scale * 0.5, scale * (i / w) as f32 / h as f32]).collect()
}

#[test]
fn compare_reports_all_metrics_as_json_for_exr_and_pfm() {
    let (r, t) = (tmp("ref.exr"), tmp("test.pfm"));
    write_image(PathBuf::from(&r).as_path(), 16, 8, &gradient(16, 8, 1.0)).unwrap();
    // The test image is the reference times 1.1 with one NaN and one +Inf channel value.
    let mut px = gradient(16, 8, 1.1);
    px[3][0] = f32::NAN;
    px[9][2] = f32::INFINITY;
    write_pfm(PathBuf::from(&t).as_path(), 16, 8, &px).unwrap();
    let o = kdtrace(&["compare", &r, &t, "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON line");
    for key in [
        "rmse",
        "relmse",
        "mae",
        "flip",
        "flip_ppd",
        "mean_ratio",
        "width",
        "height",
        "reference",
        "test",
        "skipped_values",
    ] {
        assert!(j.get(key).is_some(), "JSON lacks {key}: {j}");
    }
    assert_eq!((j["width"].as_u64(), j["height"].as_u64()), (Some(16), Some(8)));
    assert_eq!(j["test_nonfinite"]["nan"], 1);
    assert_eq!(j["test_nonfinite"]["inf"], 1);
    assert_eq!(j["reference_nonfinite"]["nan"], 0);
    assert_eq!(j["skipped_values"], 2);
    // Every finite value is 10% larger: the ratio of means is 1.1 and MAE is 0.1 × the mean.
    assert!((j["mean_ratio"].as_f64().unwrap() - 1.1).abs() < 1e-4, "{j}");
    assert!(j["rmse"].as_f64().unwrap() > 0.0 && j["flip"].as_f64().unwrap() > 0.0, "{j}");

    // Same file against itself: all zero.
    let o = kdtrace(&["compare", &r, &r, "--json"]);
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!((j["rmse"].as_f64(), j["relmse"].as_f64(), j["flip"].as_f64()), (Some(0.0), Some(0.0), Some(0.0)));
}

#[test]
fn different_sizes_exit_2_naming_both_files() {
    let (a, b) = (tmp("a.exr"), tmp("b.exr"));
    write_image(PathBuf::from(&a).as_path(), 8, 8, &gradient(8, 8, 1.0)).unwrap();
    write_image(PathBuf::from(&b).as_path(), 8, 9, &gradient(8, 9, 1.0)).unwrap();
    let o = kdtrace(&["compare", &a, &b]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains(&a) && err.contains(&b) && err.contains("8x9"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn bad_files_exit_2_naming_the_file() {
    let good = tmp("good.exr");
    write_image(PathBuf::from(&good).as_path(), 4, 4, &gradient(4, 4, 1.0)).unwrap();
    let truncated = tmp("truncated.pfm");
    std::fs::write(&truncated, b"PF\n4 4\n-1.0\n\x00\x00").unwrap();
    let garbage = tmp("garbage.exr");
    std::fs::write(&garbage, b"not an exr").unwrap();
    let png = tmp("image.png");
    std::fs::write(&png, b"x").unwrap();
    for bad in [&truncated, &garbage, &png, &tmp("missing.exr")] {
        let o = kdtrace(&["compare", &good, bad]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{bad}: {err}");
        assert!(err.contains(bad.as_str()) && !err.contains("panicked"), "{bad}: {err}");
    }
}
