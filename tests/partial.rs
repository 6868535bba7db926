//! Partial renders and merging (`render --samples A..B --partial`, `merge`) and several devices
//! at once (`render --device all`), from the command line: any split of a render's samples,
//! merged, is the single render bit for bit (its image and its variance image, so the sums and
//! the sums of squares); a part rendered on lavapipe merges with the CPU's parts alike; parts
//! of another scene, seed or size, and parts that overlap or leave samples out, are refused
//! with the files named; the CPU and lavapipe together render the CPU's image bit for bit.
use rand::{seq::SliceRandom, Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Small renders: the suite stays fast.
const IMAGE: [&str; 10] = ["--width", "24", "--height", "24", "--bounces", "3", "--seed", "7", "--sampler", "sobol"];

fn kdtrace(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kdtrace")).args(args).output().expect("run kdtrace")
}

fn ok(args: &[&str]) -> Output {
    let o = kdtrace(args);
    assert!(o.status.success(), "kdtrace {args:?} failed: {}", String::from_utf8_lossy(&o.stderr));
    o
}

/// `kdtrace ARGS` must fail with exit code 2 and a message containing each of `needles`.
fn refused(args: &[&str], needles: &[&str]) -> String {
    let o = kdtrace(args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "kdtrace {args:?} should be refused; stderr: {err}");
    assert!(!err.contains("panicked"), "{err}");
    for n in needles {
        assert!(err.contains(n), "kdtrace {args:?}: the message lacks {n:?}: {err}");
    }
    err
}

fn repo(rel: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join(rel).to_string_lossy().into_owned()
}

fn tmp(name: &str) -> String {
    let dir = std::env::temp_dir().join(format!("kdtrace-partial-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name).to_string_lossy().into_owned()
}

fn scene() -> String {
    repo("scenes/cornell-box.obj")
}

/// Renders samples `a..b` of `scene` on `device` into `out`; flags in `extra` replace IMAGE's.
fn part(scene: &str, a: u32, b: u32, device: &str, out: &str, extra: &[&str]) {
    let range = format!("{a}..{b}");
    let mut args = vec!["render", scene, "--samples", &range, "--partial", out, "--device", device];
    args.extend(IMAGE.chunks(2).filter(|flag| !extra.contains(&flag[0])).flatten());
    args.extend(extra);
    ok(&args);
}

/// The single render of samples `0..n` on `device` (`--json` and more flags in `extra`): its
/// image and variance image, as bytes, and what it printed.
fn single_with(n: u32, device: &str, name: &str, extra: &[&str]) -> (Vec<u8>, Vec<u8>, Output) {
    let (out, var) = (tmp(&format!("{name}.exr")), tmp(&format!("{name}-var.exr")));
    let (scene, spp) = (scene(), n.to_string());
    let mut args = vec!["render", &scene, "--spp", &spp, "--out", &out, "--variance", &var, "--device", device];
    args.extend(IMAGE);
    args.extend(extra);
    let o = ok(&args);
    (std::fs::read(&out).unwrap(), std::fs::read(&var).unwrap(), o)
}

fn single(n: u32, device: &str, name: &str) -> (Vec<u8>, Vec<u8>) {
    let (image, variance, _) = single_with(n, device, name, &[]);
    (image, variance)
}

/// Merges `parts` (in the order given): the image and variance image, as bytes.
fn merged(parts: &[String], name: &str) -> (Vec<u8>, Vec<u8>) {
    let (out, var) = (tmp(&format!("{name}.exr")), tmp(&format!("{name}-var.exr")));
    let mut args: Vec<&str> = vec!["merge"];
    args.extend(parts.iter().map(String::as_str));
    args.extend(["--out", &out, "--variance", &var, "--json"]);
    let o = ok(&args);
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON line");
    assert_eq!(report["parts"], parts.len());
    (std::fs::read(&out).unwrap(), std::fs::read(&var).unwrap())
}

/// `n` samples cut at `cuts` (block boundaries) into ranges.
fn ranges(n: u32, cuts: &[u32]) -> Vec<(u32, u32)> {
    let mut points = vec![0];
    points.extend(cuts);
    points.push(n);
    points.windows(2).map(|w| (w[0], w[1])).collect()
}

#[test]
fn random_splits_merge_to_the_single_render_bit_for_bit() {
    let mut rng = Pcg64::seed_from_u64(22);
    // 64 samples (8 blocks), and once 61 (a short last block).
    for (trial, n) in [64, 64, 64, 61].into_iter().enumerate() {
        let want = single(n, "cpu", &format!("single-{trial}"));
        let mut cuts: Vec<u32> = (1..n.div_ceil(8)).map(|k| 8 * k).collect();
        let pieces = rng.random_range(1..=cuts.len() + 1);
        cuts.shuffle(&mut rng);
        cuts.truncate(pieces - 1);
        cuts.sort();
        let mut files = Vec::new();
        for (i, (a, b)) in ranges(n, &cuts).into_iter().enumerate() {
            let f = tmp(&format!("t{trial}-{i}.kdp"));
            part(&scene(), a, b, "cpu", &f, &[]);
            files.push(f);
        }
        files.shuffle(&mut rng);
        let got = merged(&files, &format!("merged-{trial}"));
        assert!(got.0 == want.0, "trial {trial}: {n} samples cut at {cuts:?}: the merged image differs");
        assert!(got.1 == want.1, "trial {trial}: {n} samples cut at {cuts:?}: the merged variance differs");
    }
    // The image is not trivially equal: other samples give other bits.
    assert!(single(56, "cpu", "fewer").0 != single(64, "cpu", "all-64").0);
}

#[test]
fn a_lavapipe_part_merges_with_cpu_parts_bit_for_bit() {
    let want = single(40, "cpu", "single-40");
    let files = [tmp("l0.kdp"), tmp("l1.kdp"), tmp("l2.kdp")];
    part(&scene(), 0, 16, "cpu", &files[0], &[]);
    part(&scene(), 16, 24, "gpu", &files[1], &["--adapter", "llvmpipe"]);
    part(&scene(), 24, 40, "cpu", &files[2], &[]);
    let got = merged(&files, "merged-lavapipe");
    assert!(got.0 == want.0 && got.1 == want.1, "a part from lavapipe changes the merged image");
}

#[test]
fn mismatched_overlapping_and_missing_parts_are_refused_with_the_files_named() {
    let f = |name: &str| tmp(name);
    let (a, b, c) = (f("r0.kdp"), f("r1.kdp"), f("r2.kdp"));
    part(&scene(), 0, 16, "cpu", &a, &[]);
    part(&scene(), 16, 32, "cpu", &b, &[]);
    part(&scene(), 32, 37, "cpu", &c, &[]);
    let out = f("refused.png");
    // The parts themselves merge.
    merged(&[c.clone(), a.clone(), b.clone()], "refusal-baseline");
    // Another seed (a later flag overrides IMAGE's), another size, another scene.
    let seed = f("seed.kdp");
    part(&scene(), 16, 32, "cpu", &seed, &["--seed", "8"]);
    refused(&["merge", &a, &seed, &c, "--out", &out], &[&a, &seed, "seed 7 vs 8"]);
    let size = f("size.kdp");
    part(&scene(), 16, 32, "cpu", &size, &["--width", "20"]);
    refused(&["merge", &a, &size, &c, "--out", &out], &[&a, &size, "width"]);
    let other = f("other.kdp");
    part(&repo("scenes/uneven-noise.obj"), 16, 32, "cpu", &other, &[]);
    refused(&["merge", &a, &other, &c, "--out", &out], &[&a, &other, "different scenes"]);
    // Overlap, a gap, a missing start.
    let wide = f("wide.kdp");
    part(&scene(), 8, 24, "cpu", &wide, &[]);
    refused(&["merge", &a, &wide, &b, &c, "--out", &out], &[&a, &wide, "overlap"]);
    refused(&["merge", &a, &c, "--out", &out], &[&a, &c, "samples 16..32 are missing"]);
    refused(&["merge", &b, &c, "--out", &out], &[&b, "samples 0..16 are missing"]);
    // A part ending inside a block is a render's last: the samples after it are missing.
    let short = f("short.kdp");
    part(&scene(), 16, 20, "cpu", &short, &[]);
    refused(&["merge", &a, &short, &c, "--out", &out], &[&short, &c, "samples 20..32 are missing"]);
    // A range that does not start on a block, and files that are not parts.
    refused(
        &["render", &scene(), "--samples", "4..16", "--partial", &f("bad.kdp")],
        &["--samples 4..16", "multiple of 8"],
    );
    let damaged = f("damaged.kdp");
    let bytes = std::fs::read(&b).unwrap();
    std::fs::write(&damaged, &bytes[..bytes.len() - 100]).unwrap();
    refused(&["merge", &a, &damaged, "--out", &out], &[&damaged, "truncated"]);
    let png = f("not-a-part.png");
    std::fs::write(&png, b"\x89PNG\r\n\x1a\n").unwrap();
    refused(&["merge", &png, "--out", &out], &[&png, "not a kdtrace partial render"]);
    assert!(!Path::new(&out).exists(), "a refused merge writes no image");
}

/// `--device` for the CPU and lavapipe together: `all` where lavapipe is the only adapter, else
/// the CPU and lavapipe by index (a real GPU rounds differently).
fn cpu_and_lavapipe() -> String {
    let o = ok(&["adapters"]);
    let list = String::from_utf8_lossy(&o.stdout).into_owned();
    let names: Vec<&str> = list.lines().collect();
    let lavapipe = names.iter().position(|n| n.contains("llvmpipe")).expect("lavapipe is installed");
    if names.len() == 1 {
        "all".into()
    } else {
        format!("cpu,gpu:{lavapipe}")
    }
}

#[test]
fn every_device_at_once_renders_the_cpus_image_bit_for_bit() {
    let devices = cpu_and_lavapipe();
    let want = single(64, "cpu", "single-cpu-64");
    let (image, variance, o) = single_with(64, &devices, "all", &["--json"]);
    assert!(image == want.0, "--device {devices}: the image differs from the CPU's");
    assert!(variance == want.1, "--device {devices}: the variance differs from the CPU's");
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON line");
    let shares = report["devices"].as_array().expect("each device's share");
    assert_eq!(shares.len(), 2, "{report}");
    let blocks: Vec<u64> = shares.iter().map(|s| s["blocks"].as_u64().unwrap()).collect();
    assert!(blocks.iter().all(|&b| b >= 1), "each device renders a block: {blocks:?}");
    assert_eq!(blocks.iter().sum::<u64>(), 8);
    let total: f64 = shares.iter().map(|s| s["share"].as_f64().unwrap()).sum();
    assert!((total - 1.0).abs() < 1e-9, "{report}");
    // Several devices write parts too: their blocks merge with a CPU part.
    let (p0, p1) = (tmp("all-0.kdp"), tmp("all-1.kdp"));
    part(&scene(), 0, 40, &devices, &p0, &[]);
    part(&scene(), 40, 64, "cpu", &p1, &[]);
    assert!(merged(&[p0, p1], "merged-all") == want, "--device {devices} --partial: the merge differs");
    // Adaptive sampling is one device's.
    refused(
        &["render", &scene(), "--out", &tmp("adaptive.png"), "--device", &devices, "--adaptive", "0.05"],
        &["--adaptive"],
    );
}
