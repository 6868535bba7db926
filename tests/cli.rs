//! The command line as a user meets it: the README's render, JSON output, verify's exit code,
//! and bad input that gets exit code 2 and a message naming the file (never a panic).
use std::{
    path::{Path, PathBuf},
    process::{Command, Output},
};

fn kdtrace(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kdtrace")).args(args).output().expect("run kdtrace")
}

fn repo(rel: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join(rel).to_string_lossy().into_owned()
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("kdtrace-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Whether no pixel of `image` has any light.
fn black(image: &[[f32; 3]]) -> bool {
    !image.iter().any(|p| p.iter().any(|&c| c > 0.0))
}

/// How many pixels of `a` and `b` differ in any bit.
fn pixels_differing(a: &[[f32; 3]], b: &[[f32; 3]]) -> usize {
    a.iter().zip(b).filter(|(a, b)| a.map(f32::to_bits) != b.map(f32::to_bits)).count()
}

#[test]
fn renders_the_default_scene_on_both_devices_with_json() {
    for device in ["cpu", "gpu"] {
        let out = tmp(&format!("cornell-{device}.png"));
        let o = kdtrace(&[
            "render",
            &repo("scenes/cornell-box.obj"),
            "--out",
            out.to_str().unwrap(),
            "--device",
            device,
            "--spp",
            "4",
            "--width",
            "40",
            "--height",
            "30",
            "--json",
        ]);
        assert!(o.status.success(), "{device}: {}", stderr(&o));
        let line: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON line");
        for key in [
            "device",
            "adapter",
            "triangles",
            "spp",
            "width",
            "height",
            "load_s",
            "build_s",
            "prepare_s",
            "render_s",
            "samples_per_s",
        ] {
            assert!(line.get(key).is_some(), "{device}: JSON lacks {key}: {line}");
        }
        assert_eq!(line["device"], device);
        assert_eq!(line["triangles"], 32);
        // The Cornell box: its lamp (two triangles), diffuse walls, light after bounces.
        let f = &line["features"];
        assert_eq!((f["emitters"].as_u64(), f["environment"].as_str()), (Some(2), Some("black")), "{f}");
        assert_eq!((f["indirect"].as_bool(), f["variant"].as_str()), (Some(true), Some("specialised")), "{f}");
        // Emitters, many emitters, diffuse, indirect light and the light subpaths' connections
        // (bit 14), drawn from the pool: the variant of both devices.
        let bits = 27 | 1 << 14;
        assert_eq!((f["bits"].as_u64(), f["variant_bits"].as_u64()), (Some(bits), Some(bits)), "{f}");
        assert_eq!((f["connect"].as_bool(), f["light_pool"].as_bool()), (Some(true), Some(true)), "{f}");
        assert!(f["seen_light_share"].is_null(), "{f}");
        assert_eq!(
            (line["width"].as_u64(), line["height"].as_u64(), line["spp"].as_u64()),
            (Some(40), Some(30), Some(4))
        );
        let img = image::open(&out).unwrap();
        assert_eq!((img.width(), img.height()), (40, 30));
        let bright = img.to_rgb8().pixels().filter(|p| p.0.iter().any(|&c| c > 20)).count();
        assert!(bright > 600, "{device}: image mostly black ({bright} lit pixels)");
    }
}

#[test]
fn writes_linear_exr() {
    let out = tmp("cornell.exr");
    let o = kdtrace(&[
        "render",
        &repo("scenes/cornell-box.obj"),
        "--out",
        out.to_str().unwrap(),
        "--spp",
        "2",
        "--width",
        "16",
        "--height",
        "16",
        "--bounces",
        "0",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h, px) = kdtrace::image::io::read_exr(&out).unwrap();
    assert_eq!((w, h, px.len()), (16, 16, 256));
    // Linear radiance: the light itself is far above 1.
    assert!(px.iter().any(|p| p[0] > 2.0), "no HDR values in the EXR");
}

#[test]
fn verify_agrees_and_says_so() {
    let scene = repo("scenes/cornell-box.obj");
    // The specialised variants (the default) and the generic code.
    for specialize in ["on", "off"] {
        let args = ["verify", &scene, "--spp", "4", "--width", "32", "--height", "32", "--json", "--specialize"];
        let o = kdtrace(&[&args[..], &[specialize]].concat());
        assert!(o.status.success(), "{}", stderr(&o));
        let line: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(line["agreement"]["pass"], true, "{line}");
        assert_eq!(line["agreement"]["pixels"], 1024);
        // On lavapipe the two devices agree bit for bit.
        if line["adapter"].as_str().unwrap().contains("llvmpipe") {
            assert_eq!(line["agreement"]["bitwise_identical_pixels"], 1024, "{line}");
        }
    }
}

fn write(name: &str, text: &str) -> PathBuf {
    let p = tmp(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn expect_input_error(args: &[&str], needle: &str) {
    let o = kdtrace(args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "args {args:?}: expected exit 2, got {:?}; stderr: {err}", o.status.code());
    assert!(err.contains(needle), "args {args:?}: stderr lacks {needle:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn bad_input_exits_2_with_the_file_and_line() {
    let out = tmp("never.png");
    let out = out.to_str().unwrap();
    let missing = tmp("missing.obj");
    expect_input_error(&["render", missing.to_str().unwrap(), "--out", out], "missing.obj");
    let nan = write("nan.obj", "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n");
    expect_input_error(&["render", nan.to_str().unwrap(), "--out", out], "nan.obj:3");
    let huge = write("huge.obj", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n");
    expect_input_error(&["render", huge.to_str().unwrap(), "--out", out], "huge.obj:2");
    let empty = write("empty.obj", "# nothing\n");
    expect_input_error(&["render", empty.to_str().unwrap(), "--out", out], "no triangles");
    let bad_index = write("index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    expect_input_error(&["render", bad_index.to_str().unwrap(), "--out", out], "index.obj");
    let cornell = repo("scenes/cornell-box.obj");
    expect_input_error(&["render", &cornell, "--out", out, "--spp", "0"], "spp");
    expect_input_error(
        &["verify", &cornell, "--time-limit", "1", "--spp", "1", "--width", "4", "--height", "4"],
        "--time-limit does not apply",
    );
    expect_input_error(&["render", &cornell, "--out", out, "--width", "0"], "resolution");
    expect_input_error(&["render", &cornell, "--out", out, "--eye", "0,0,0", "--target", "0,0,0"], "eye and target");
    expect_input_error(
        &["render", &cornell, "--out", tmp("x.bmp").to_str().unwrap(), "--spp", "1", "--width", "4", "--height", "4"],
        "x.bmp",
    );
    expect_input_error(
        &["render", &cornell, "--out", out, "--device", "gpu", "--adapter", "no-such-adapter", "--spp", "1"],
        "no-such-adapter",
    );
    expect_input_error(
        &["render", &cornell, "--out", out, "--device", "gpu", "--traversal", "wide", "--spp", "1"],
        "--traversal wide",
    );
    assert!(!Path::new(out).exists(), "a failed render wrote its output");
}

/// `render SCENE --out OUT` at 8×8 and 1 spp with `--json`, and `extra`.
fn tiny_render(scene: &str, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec!["render", scene, "--out", out.to_str().unwrap(), "--spp", "1", "--width", "8", "--height", "8"];
    args.extend_from_slice(extra);
    args.push("--json");
    kdtrace(&args)
}

/// The CPU path renders on its wide BVH unless told otherwise, reports it, and counts its build;
/// on the BVH it builds no k-d tree (no `nodes`), for `--traversal full` only the k-d tree.
#[test]
fn the_cpu_path_renders_on_its_wide_bvh() {
    let cornell = repo("scenes/cornell-box.obj");
    for (flag, expected) in [("auto", "wide"), ("wide", "wide"), ("full", "full")] {
        let o = tiny_render(&cornell, &tmp(&format!("traversal-{flag}.png")), &["--traversal", flag]);
        assert!(o.status.success(), "{}", stderr(&o));
        let j: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON line");
        assert_eq!(j["traversal"], expected, "--traversal {flag}");
        assert!(j["build_s"].as_f64().unwrap() > 0.0);
        // The BVH's size where it was built: every triangle in some leaf, at most eight a leaf.
        let bvh = &j["wide_bvh"];
        if expected == "wide" {
            let (refs, leaves) = (bvh["references"].as_u64().unwrap(), bvh["leaves"].as_u64().unwrap());
            assert!(refs >= j["triangles"].as_u64().unwrap() && refs <= 8 * leaves, "{bvh}");
            assert!(bvh["nodes"].as_u64().unwrap() >= 1 && bvh["depth"].as_u64().unwrap() >= 1, "{bvh}");
            assert!(j["nodes"].is_null() && j["tree_depth"].is_null(), "--traversal {flag} built a k-d tree: {j}");
        } else {
            assert!(bvh.is_null(), "--traversal {flag} built a BVH: {bvh}");
            assert!(j["nodes"].as_u64().unwrap() >= 1 && j["tree_depth"].as_u64().unwrap() >= 1, "{j}");
        }
    }
}

#[test]
fn missing_material_library_renders_grey() {
    let obj = write("nomtl.obj", "mtllib absent.mtl\nv -1 -1 0\nv 1 -1 0\nv 0 1 0\nusemtl whatever\nf 1 2 3\n");
    let o = tiny_render(obj.to_str().unwrap(), &tmp("nomtl.png"), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("material library not found"), "{}", stderr(&o));
}

/// A scene that nothing lights renders black and says why; a constant environment lights it,
/// and the warning goes.
#[test]
fn a_scene_without_light_warns_that_it_renders_black() {
    let obj = write("unlit.obj", "v -1 -1 -3\nv 1 -1 -3\nv 0 1 -3\nf 1 2 3\n");
    let camera = ["--eye", "0,0,0", "--target", "0,0,-1", "--up", "0,1,0", "--fov", "60"];
    let warning = "nothing emits light";
    for (extra, lit) in [(&[][..], false), (&["--environment", "1,1,1"][..], true)] {
        let out = tmp(&format!("unlit-{lit}.exr"));
        let o = tiny_render(obj.to_str().unwrap(), &out, &[&camera[..], extra].concat());
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        assert_eq!(stderr(&o).contains(warning), !lit, "{extra:?}: {}", stderr(&o));
        let (_, _, px) = kdtrace::image::io::read_exr(&out).unwrap();
        assert_eq!(black(&px), !lit, "{extra:?}");
    }
}

/// `--specialize off` writes the same file as the specialised default, and says which ran;
/// `--adaptive` reports the spread of samples per pixel.
#[test]
fn specialisation_and_adaptive_sampling_from_the_command_line() {
    let scene = repo("scenes/uneven-noise.toml");
    let json = |out: &Path, extra: &[&str]| {
        let mut args = vec!["render", &scene, "--out", out.to_str().unwrap(), "--spp", "16", "--width", "24"];
        args.extend_from_slice(&["--height", "18", "--json"]);
        args.extend_from_slice(extra);
        let o = kdtrace(&args);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        let text = String::from_utf8(o.stdout).unwrap();
        serde_json::from_str::<serde_json::Value>(text.lines().last().unwrap()).unwrap()
    };
    let (on, off) = (tmp("special.exr"), tmp("generic.exr"));
    let a = json(&on, &[]);
    let b = json(&off, &["--specialize", "off"]);
    assert_eq!(a["features"]["variant"], "specialised");
    assert_eq!(b["features"]["variant"], "generic");
    assert_ne!(a["features"]["variant_bits"], b["features"]["variant_bits"]);
    // Pixels compared, not bytes: the EXR encoder compresses blocks in parallel, in any order.
    let pixels = |p: &Path| kdtrace::image::io::read_exr(p).unwrap().2;
    assert!(pixels(&on) == pixels(&off), "--specialize off changed the image");
    let c = json(&tmp("adaptive.exr"), &["--adaptive", "0.1", "--min-spp", "4"]);
    let (lo, mean, hi) = (c["spp_min"].as_u64().unwrap(), c["spp_mean"].as_f64().unwrap(), c["spp"].as_u64().unwrap());
    assert!(lo as f64 <= mean && mean <= hi as f64 && hi <= 16 && lo < hi, "{c}");
    assert_eq!(c["adaptive"]["mode"], "pilot");
    assert_eq!(c["adaptive"]["min_spp"], 4);
}

/// `compile` takes the tree's build settings: a depth limit of 1 stores at most three nodes.
#[test]
fn compile_takes_build_settings() {
    let scene = repo("scenes/cornell-box.obj");
    let nodes = |out: &Path, extra: &[&str]| {
        let o = kdtrace(&[&["compile", &scene, "--out", out.to_str().unwrap(), "--json"][..], extra].concat());
        assert!(o.status.success(), "{}", stderr(&o));
        let line: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        line["nodes"].as_u64().unwrap()
    };
    let deep = nodes(&tmp("deep.kdc"), &[]);
    let shallow = nodes(&tmp("shallow.kdc"), &["--max-depth", "1"]);
    assert!(shallow <= 3 && deep > shallow, "{deep} and {shallow} nodes");
    let o = kdtrace(&[
        "render",
        tmp("shallow.kdc").to_str().unwrap(),
        "--out",
        tmp("s.png").to_str().unwrap(),
        "--spp",
        "1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// The CPU integrator compiled for AVX-512 (where this CPU has it, the default) and for the
/// build's own target (`KDTRACE_CPU_ISA=baseline`) renders the same image bit for bit, through
/// the diffuse variant, textures, the other materials and an environment map; `--json` names
/// the instruction set that ran. Where the CPU lacks AVX-512 both runs take the build's target
/// and only the names are checked.
#[test]
fn cpu_instruction_sets_render_the_same_image() {
    #[cfg(target_arch = "x86_64")]
    let avx512 = std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512vl")
        && std::arch::is_x86_feature_detected!("avx512bw")
        && std::arch::is_x86_feature_detected!("avx512dq")
        && std::arch::is_x86_feature_detected!("avx512cd");
    #[cfg(not(target_arch = "x86_64"))]
    let avx512 = false;
    let scenes = [
        "scenes/cornell-box.obj",
        "tests/data/cornell-textured/cornell-textured.toml",
        "tests/data/cornell-materials/cornell-roughplastic.toml",
        "tests/data/cornell-materials/cornell-glass.toml",
        "tests/data/environment/sky-scene.toml",
    ];
    for (i, scene) in scenes.iter().enumerate() {
        let mut images = Vec::new();
        for isa in ["default", "baseline"] {
            let out = tmp(&format!("isa-{i}-{isa}.exr"));
            let args = ["render", &repo(scene), "--out", out.to_str().unwrap(), "--device", "cpu", "--json"];
            // Eleven samples, 23 pixels a row: a block of eight (groups of two pixels), then three
            // samples (groups of five pixels and one, the row's last five samples through the
            // scalar code).
            let size = ["--spp", "11", "--width", "23", "--height", "20", "--bounces", "4"];
            let mut cmd = Command::new(env!("CARGO_BIN_EXE_kdtrace"));
            cmd.args(args).args(size);
            if isa == "baseline" {
                cmd.env("KDTRACE_CPU_ISA", "baseline");
            }
            let o = cmd.output().unwrap();
            assert!(o.status.success(), "{scene}: {}", stderr(&o));
            let line: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
            let adapter = line["adapter"].as_str().unwrap().to_owned();
            let expected = if avx512 && isa == "default" { "x86-64-v4" } else { "threads, " };
            assert!(adapter.contains(expected), "{scene}, {isa}: {adapter}");
            if isa == "baseline" {
                assert!(!adapter.contains("x86-64-v4"), "{scene}: {adapter}");
            }
            let (_, _, px) = kdtrace::image::io::read_exr(&out).unwrap();
            images.push(px);
        }
        assert!(!black(&images[0]), "{scene}: a black image");
        let differ = pixels_differing(&images[0], &images[1]);
        assert_eq!(differ, 0, "{scene}: {differ} pixels differ between the instruction sets");
    }
}

/// The lane integrator (`shared::lanes`, sixteen samples of a pixel at once) renders what the
/// scalar integrator renders (`KDTRACE_CPU_LANES=off`), bit for bit, on the scenes it covers:
/// one and many emitters, a constant environment (the bunny's sky), textures, direct light alone and paths long enough for
/// Russian roulette and the sampler's independent sets, both samplers, sample counts that leave
/// a group part-filled or fill it from several pixels (one, three or ten samples a pixel, 23
/// pixels a row), adaptive sampling's uneven counts, and every material kind: rough and
/// smooth glass, rough plastic, a rough conductor, MTL mirrors and glass, and glTF principled
/// materials with textures, masks and transmission; an environment map and punctual lights; a
/// mesh in a box, whose walls the lanes test apart (`lanes::split`). `render --json` says which
/// ran. (Absorbing media: `tests/gltf_lights_and_media.rs`, against
/// lavapipe.)
#[test]
fn lane_integrator_renders_the_scalar_image() {
    // The Cornell box's emitter with every other kind of light: a map, a point, a spot and a
    // directional light.
    let lights = tmp("lanes-lights.toml");
    let sky = repo("tests/data/environment/sky.exr");
    let mesh = repo("scenes/cornell-box.obj");
    let toml = format!(
        r#"environment = {{ file = {sky:?}, strength = 0.5 }}
[[mesh]]
file = {mesh:?}
[[light]]
type = "point"
position = [0.25, 0.4, -0.25]
intensity = 0.3
[[light]]
type = "spot"
position = [0.4, 0.5, -0.1]
direction = [0, -1, 0]
intensity = 1
inner_cone_angle = 0.2
outer_cone_angle = 0.5
[[light]]
type = "directional"
direction = [-0.3, -0.2, -1]
intensity = 2
"#
    );
    std::fs::write(&lights, toml).unwrap();
    let lights = lights.to_string_lossy().into_owned();
    // A bunny of 3,674 triangles in the Cornell box: the lanes test the box's walls sixteen rays
    // at a time and traverse a BVH over the rest (`lanes::split`).
    let boxed = tmp("lanes-split.toml");
    let bunny = repo("tests/data/meshes/bunny-npm/bunny.obj");
    std::fs::write(
        &boxed,
        format!(
            "[[mesh]]\nfile = {mesh:?}\n[[mesh]]\nfile = {bunny:?}\nscale = 0.02\ntranslate = [0.28, 0.0, -0.28]\n"
        ),
    )
    .unwrap();
    let boxed = boxed.to_string_lossy().into_owned();
    let cases: [(&str, &[&str]); 20] = [
        ("scenes/cornell-box.obj", &["--spp", "21", "--bounces", "6"]),
        ("scenes/cornell-box.obj", &["--spp", "1", "--bounces", "6"]),
        ("tests/data/meshes/CornellBox-Original/CornellBox-Original.obj", &["--spp", "10", "--bounces", "5"]),
        (
            "scenes/uneven-noise.obj",
            &["--spp", "3", "--bounces", "6", "--eye=0.4,1.0,3.9", "--target=2.6,1.0,0.5", "--fov=70"],
        ),
        ("scenes/cornell-box.obj", &["--spp", "16", "--bounces", "0", "--sampler", "independent"]),
        ("scenes/bunny.toml", &["--spp", "9", "--bounces", "3", "--seed", "7"]),
        (
            "scenes/uneven-noise.obj",
            &[
                "--spp",
                "35",
                "--bounces",
                "8",
                "--eye=0.4,1.0,3.9",
                "--target=2.6,1.0,0.5",
                "--fov=70",
                "--connect",
                "on",
            ],
        ),
        ("tests/data/meshes/CornellBox-Original/CornellBox-Original.obj", &["--spp", "17", "--bounces", "6"]),
        ("tests/data/cornell-textured/cornell-textured.toml", &["--spp", "18", "--bounces", "4"]),
        (
            "scenes/uneven-noise.obj",
            &[
                "--spp",
                "24",
                "--adaptive",
                "0.05",
                "--min-spp",
                "6",
                "--eye=0.4,1.0,3.9",
                "--target=2.6,1.0,0.5",
                "--fov=70",
            ],
        ),
        ("tests/data/cornell-materials/cornell-glass.toml", &["--spp", "19", "--bounces", "8"]),
        ("tests/data/cornell-materials/cornell-smooth-glass.toml", &["--spp", "16", "--bounces", "8"]),
        ("tests/data/cornell-materials/cornell-roughplastic.toml", &["--spp", "16", "--bounces", "5"]),
        ("tests/data/cornell-metal/cornell-metal.toml", &["--spp", "20", "--bounces", "6", "--seed", "3"]),
        ("tests/data/meshes/CornellBox-Sphere/CornellBox-Sphere.obj", &["--spp", "16", "--bounces", "8"]),
        ("tests/data/gltf/TransmissionTest/TransmissionTest.gltf", &["--spp", "16", "--bounces", "6"]),
        ("tests/data/environment/sky-scene.toml", &["--spp", "24", "--bounces", "6"]),
        ("tests/data/gltf/EmissiveStrengthTest/EmissiveStrengthTest.gltf", &["--spp", "16", "--bounces", "4"]),
        (&lights, &["--spp", "20", "--bounces", "5"]),
        (&boxed, &["--spp", "19", "--bounces", "6"]),
    ];
    for (k, (scene, extra)) in cases.iter().enumerate() {
        let mut images = Vec::new();
        for lanes in [true, false] {
            let out = tmp(&format!("lanes-{k}-{lanes}.exr"));
            let args = ["render", &repo(scene), "--out", out.to_str().unwrap(), "--device", "cpu", "--json"];
            let mut cmd = Command::new(env!("CARGO_BIN_EXE_kdtrace"));
            cmd.args(args).args(["--width", "23", "--height", "19"]).args(*extra);
            if !lanes {
                cmd.env("KDTRACE_CPU_LANES", "off");
            }
            let o = cmd.output().unwrap();
            assert!(o.status.success(), "{scene} {extra:?}: {}", stderr(&o));
            let line: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
            assert_eq!(line["features"]["lanes"], lanes, "{scene} {extra:?}: {line}");
            // Every connection draws its light subpath from the pool (uneven-noise connects,
            // asked to or by `auto`).
            let f = &line["features"];
            assert_eq!(f["light_pool"], f["connect"], "{scene} {extra:?}: {line}");
            assert!(!scene.contains("uneven-noise") || f["connect"] == true, "{scene} {extra:?}: {line}");
            if *scene == boxed {
                // Only a render through the lanes builds the split.
                let split = line["wide_bvh"]["split_large"].as_u64().unwrap() > 0;
                assert_eq!(split, lanes, "split built: {split}: {line}");
            }
            let (_, _, px) = kdtrace::image::io::read_exr(&out).unwrap();
            images.push(px);
        }
        assert!(!black(&images[0]), "{scene} {extra:?}: a black image");
        let differ = pixels_differing(&images[0], &images[1]);
        assert_eq!(differ, 0, "{scene} {extra:?}: {differ} pixels differ between the lane and scalar integrators");
    }
    // The generic code (the reference every variant is tested against) and the AOVs run the
    // scalar integrator.
    for (scene, extra) in
        [("scenes/cornell-box.obj", &["--specialize", "off"][..]), ("scenes/cornell-box.obj", &["--aov", "albedo"][..])]
    {
        let out = tmp("lanes-not.exr");
        let o = kdtrace(
            &[
                &[
                    "render",
                    &repo(scene),
                    "--out",
                    out.to_str().unwrap(),
                    "--json",
                    "--spp",
                    "16",
                    "--width",
                    "8",
                    "--height",
                    "8",
                ][..],
                extra,
            ]
            .concat(),
        );
        assert!(o.status.success(), "{scene}: {}", stderr(&o));
        let line: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(line["features"]["lanes"], false, "{scene} {extra:?}: {line}");
    }
}

/// `rays` casts the same rays with the same results under both instruction sets (its batch
/// casting has an AVX-512 copy too): hits, nodes and triangle tests per ray, for the three ray
/// kinds, on a mesh of 23k triangles whose wide BVH is several levels deep.
#[test]
fn cpu_instruction_sets_cast_the_same_rays() {
    let mut runs = Vec::new();
    for isa in ["default", "baseline"] {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_kdtrace"));
        let scene = repo("tests/data/meshes/dragon-23k/dragon.obj");
        cmd.args(["rays", &scene, "--width", "48", "--height", "40", "--repeats", "1", "--json"]);
        if isa == "baseline" {
            cmd.env("KDTRACE_CPU_ISA", "baseline");
        }
        let o = cmd.output().unwrap();
        assert!(o.status.success(), "{isa}: {}", stderr(&o));
        let kinds: Vec<[serde_json::Value; 4]> = String::from_utf8(o.stdout)
            .unwrap()
            .lines()
            .map(|l| {
                let j: serde_json::Value = serde_json::from_str(l).unwrap();
                [j["kind"].clone(), j["hits"].clone(), j["nodes_per_ray"].clone(), j["tests_per_ray"].clone()]
            })
            .collect();
        assert_eq!(kinds.len(), 3, "{isa}: {kinds:?}");
        assert!(kinds.iter().all(|k| k[1].as_u64().unwrap() > 0 && k[2].as_f64().unwrap() > 1.0), "{isa}: {kinds:?}");
        runs.push(kinds);
    }
    assert_eq!(runs[0], runs[1], "the instruction sets cast different rays");
}

/// `rays --pixel-samples N` casts N camera rays a pixel (and as many AO and diffuse rays from
/// their hits), and packets of one pixel's samples find the hits single rays find.
#[test]
fn rays_take_several_samples_a_pixel() {
    let mut runs = Vec::new();
    for packets in [false, true] {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_kdtrace"));
        let scene = repo("tests/data/meshes/dragon-23k/dragon.obj");
        cmd.args([
            "rays",
            &scene,
            "--width",
            "12",
            "--height",
            "10",
            "--pixel-samples",
            "16",
            "--repeats",
            "1",
            "--json",
        ]);
        if packets {
            cmd.arg("--packets");
        }
        let o = cmd.output().unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
        let kinds: Vec<(String, u64, u64)> = String::from_utf8(o.stdout)
            .unwrap()
            .lines()
            .map(|l| {
                let j: serde_json::Value = serde_json::from_str(l).unwrap();
                assert_eq!(j["pixel_samples"], 16, "{l}");
                (j["kind"].as_str().unwrap().to_string(), j["rays"].as_u64().unwrap(), j["hits"].as_u64().unwrap())
            })
            .collect();
        assert_eq!(kinds[0].0, "primary");
        assert_eq!(kinds[0].1, 12 * 10 * 16, "{kinds:?}");
        // Jittered: some of a pixel's samples leave the dragon's silhouette where others hit it.
        assert!(kinds[0].2 > 0 && kinds[0].2 < kinds[0].1, "{kinds:?}");
        assert_eq!(kinds[1].1, kinds[0].2, "one AO ray from every camera ray's hit: {kinds:?}");
        runs.push(kinds);
    }
    assert_eq!(runs[0], runs[1], "packets found other hits than single rays");
}

/// A reader that leaves early (`| head -1`) ends the command quietly: no panic, exit code 0.
#[test]
fn closed_standard_output_ends_quietly() {
    for args in [&["rays", "--width", "16", "--height", "16", "--json"][..], &["tree", "--json"][..], &["tree"][..]] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_kdtrace"))
            .arg(args[0])
            .arg(repo("scenes/cornell-box.obj"))
            .args(&args[1..])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // Close the read end before the command writes anything.
        drop(child.stdout.take());
        let o = child.wait_with_output().unwrap();
        assert!(o.status.success(), "{args:?}: {:?}, {}", o.status, stderr(&o));
        assert!(!stderr(&o).contains("panicked"), "{args:?}: {}", stderr(&o));
    }
}
