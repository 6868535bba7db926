//! Compiled scenes (`.kdc`): what is written reads back bit for bit and renders the same image;
//! truncated, corrupted, other-version and crafted files are refused with a message naming the
//! file, never used and never a panic.
#[path = "common/kdc_craft.rs"]
mod craft;

#[path = "common/paths.rs"]
mod paths;
use kdtrace::{
    kdbuild::BuildSettings,
    render::{kdc, Compiled},
};
use paths::repo;
use std::{
    path::{Path, PathBuf},
    process::Command,
};

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("kdtrace-kdc-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn assert_same(a: &Compiled, b: &Compiled) {
    let bits = |x: &[u8]| x.to_vec();
    assert_eq!(bits(bytemuck::cast_slice(&a.scene.triangles)), bits(bytemuck::cast_slice(&b.scene.triangles)));
    assert_eq!(a.scene.info, b.scene.info);
    assert_eq!(bits(bytemuck::cast_slice(&a.scene.materials)), bits(bytemuck::cast_slice(&b.scene.materials)));
    assert_eq!(a.scene.material_names, b.scene.material_names);
    // Textures, then the rough plastics' coating tables.
    assert_eq!(a.scene.textures, b.scene.textures);
    assert_eq!(bits(bytemuck::cast_slice(&a.scene.lights)), bits(bytemuck::cast_slice(&b.scene.lights)));
    assert_eq!(a.lights, b.lights);
    assert_eq!(
        (a.scene.bounds_min, a.scene.bounds_max, a.scene.dropped_degenerate),
        (b.scene.bounds_min, b.scene.bounds_max, b.scene.dropped_degenerate)
    );
    assert_eq!(a.tree().nodes, b.tree().nodes);
    assert_eq!(a.tree().indices, b.tree().indices);
    assert_eq!(
        (a.tree().bounds_min, a.tree().bounds_max, a.tree().depth),
        (b.tree().bounds_min, b.tree().bounds_max, b.tree().depth)
    );
    assert_eq!(a.origin, b.origin);
}

/// A scene 1e5 away loads into its local frame; the `.kdc` keeps the frame's origin, and the
/// camera, given in world space, sees the same image from the file as from the scene.
#[test]
fn a_far_scene_keeps_its_local_frame_through_a_kdc() {
    let toml = tmp("far.toml");
    let obj = repo("scenes/cornell-box.obj");
    std::fs::write(
        &toml,
        format!(
            "[camera]\neye = [100000.278, 100000.273, 100000.8]\ntarget = [100000.278, 100000.273, 99999.72]\nwidth = 16\nheight = 16\n\n[render]\nspp = 4\nbounces = 2\n\n[[mesh]]\nfile = {:?}\ntranslate = [100000, 100000, 100000]\n",
            obj.to_string_lossy()
        ),
    )
    .unwrap();
    let loaded = kdtrace::load(&toml, BuildSettings::default()).unwrap();
    let origin = loaded.compiled.origin;
    assert!(origin.min_element() > 99_999.0, "not moved into a local frame: origin {origin}");
    assert!(
        loaded.compiled.tree().bounds_max.abs().max_element() < 1.0,
        "local bounds {:?}",
        loaded.compiled.tree().bounds_max
    );
    let path = tmp("far.kdc");
    kdc::write(&path, &loaded.compiled, &BuildSettings::default(), &loaded.settings).unwrap();
    let back = kdc::read(&path).unwrap();
    assert_same(&loaded.compiled, &back.compiled);
    let (lo, hi) = loaded.compiled.world_bounds();
    let s = loaded.settings.resolve(lo, hi).unwrap();
    let none = |_: u64, _: u64| {};
    let a = kdtrace::render::cpu::render(&loaded.compiled, &s, &none).unwrap();
    let b = kdtrace::render::cpu::render(&back.compiled, &s, &none).unwrap();
    assert_eq!(a.sum, b.sum);
    // The camera sees the box: most pixels are lit.
    let lit = a.mean().iter().filter(|p| p[0] + p[1] + p[2] > 0.01).count();
    assert!(lit > 16 * 16 / 2, "only {lit} of 256 pixels lit: the camera missed the box");
}

fn cornell_bytes() -> (Vec<u8>, kdtrace::Loaded) {
    let loaded = kdtrace::load(&repo("scenes/cornell-box.toml"), BuildSettings::default()).unwrap();
    (kdc::encode(&loaded.compiled, &BuildSettings::default(), &loaded.settings).unwrap(), loaded)
}

#[test]
fn written_scenes_read_back_bit_for_bit() {
    for rel in [
        "scenes/cornell-box.toml",
        "tests/data/meshes/CornellBox-Sphere/CornellBox-Sphere.obj",
        "tests/data/meshes/bunny-npm/bunny.obj",
        "tests/data/cornell-materials/cornell-roughplastic.toml",
    ] {
        let loaded = kdtrace::load(&repo(rel), BuildSettings::default()).unwrap();
        if rel.contains("roughplastic") {
            // The coating's table travels in the texture section.
            let rough = loaded.compiled.scene.materials.iter().find(|m| m.params.x > 0.0).unwrap();
            let words = shared::material::ROUGH_PLASTIC_TABLE_WORDS as usize;
            assert_eq!(loaded.compiled.scene.textures.len(), rough.table as usize + words);
        }
        let path = tmp(&format!("{}.kdc", Path::new(rel).file_stem().unwrap().to_string_lossy()));
        let build = BuildSettings { leaf_size: 3, ..BuildSettings::default() };
        kdc::write(&path, &loaded.compiled, &build, &loaded.settings).unwrap();
        let back = kdc::read(&path).unwrap();
        assert_same(&loaded.compiled, &back.compiled);
        assert_eq!(back.settings, loaded.settings, "{rel}");
        assert_eq!(serde_json::to_value(back.build_settings).unwrap(), serde_json::to_value(build).unwrap());
        // And through the extension dispatch.
        let via_load = kdtrace::load(&path, BuildSettings::default()).unwrap();
        assert_eq!(via_load.kind, kdtrace::SceneKind::Kdc);
        assert_eq!(via_load.build_s, 0.0);
        assert_same(&loaded.compiled, &via_load.compiled);
    }
}

#[test]
fn a_kdc_renders_the_image_its_source_renders() {
    let out = tmp("cornell-kdc.kdc");
    let bin = env!("CARGO_BIN_EXE_kdtrace");
    let o = Command::new(bin)
        .args(["compile", repo("scenes/cornell-box.toml").to_str().unwrap(), "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut images = Vec::new();
    for src in [repo("scenes/cornell-box.toml"), out.clone()] {
        let png = tmp(&format!("{}.png", src.extension().unwrap().to_string_lossy()));
        let o = Command::new(bin)
            .args([
                "render",
                src.to_str().unwrap(),
                "--out",
                png.to_str().unwrap(),
                "--spp",
                "2",
                "--width",
                "24",
                "--height",
                "16",
                "--json",
            ])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        images.push(image::open(&png).unwrap().to_rgb8().into_raw());
    }
    assert_eq!(images[0], images[1], "the .kdc renders differently from its source");
    assert!(images[0].iter().any(|&c| c > 50), "black image");
}

#[test]
fn every_truncation_is_refused() {
    let (bytes, _) = cornell_bytes();
    let path = Path::new("cut.kdc");
    for len in 0..bytes.len() {
        let e =
            kdc::decode(path, &bytes[..len]).err().unwrap_or_else(|| panic!("a file cut to {len} bytes was accepted"));
        assert!(format!("{e:#}").contains("cut.kdc"), "{e:#}");
    }
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(kdc::decode(path, &longer).is_err());
    assert!(kdc::decode(path, &bytes).is_ok());
}

#[test]
fn every_single_bit_flip_is_refused() {
    let (bytes, _) = cornell_bytes();
    for i in 0..bytes.len() {
        for bit in [0, 5] {
            let mut b = bytes.clone();
            b[i] ^= 1 << bit;
            let e = kdc::decode(Path::new("flip.kdc"), &b)
                .err()
                .unwrap_or_else(|| panic!("flipping bit {bit} of byte {i} went unnoticed"));
            assert!(format!("{e:#}").contains("flip.kdc"));
        }
    }
}

#[test]
fn another_format_version_is_refused_by_name() {
    let (bytes, _) = cornell_bytes();
    let mut p = craft::split(&bytes);
    p.version = kdc::FORMAT_VERSION + 1;
    let e = format!("{:#}", kdc::decode(Path::new("old.kdc"), &craft::join(&p)).err().unwrap());
    let named = format!("format version {}", kdc::FORMAT_VERSION + 1);
    assert!(e.contains("old.kdc") && e.contains(&named) && e.contains("kdtrace compile"), "{e}");
}

/// Edits behind a valid checksum, each with the words its refusal must contain.
#[test]
fn crafted_files_are_refused_behind_a_valid_checksum() {
    let (bytes, loaded) = cornell_bytes();
    let c = &loaded.compiled;
    type Edit = Box<dyn Fn(&mut craft::Parts)>;
    let node = move |p: &craft::Parts, i: usize| craft::section_offset(p, 4) + 8 * i;
    let first_interior = c.tree().nodes.iter().position(|n| !n.is_leaf()).unwrap();
    let first_leaf = c.tree().nodes.iter().position(|n| n.is_leaf() && n.count() > 0).unwrap();
    let ax = c.tree().nodes[first_interior].axis();
    let cases: Vec<(&str, Edit)> = vec![
        ("children", Box::new(move |p| craft::put_u32(p, node(p, first_interior) + 4, ax | (9999 << 2)))),
        (
            "children",
            Box::new(move |p| craft::put_u32(p, node(p, first_interior) + 4, ax | ((first_interior as u32 + 1) << 2))),
        ),
        ("split", Box::new(move |p| craft::put_f32(p, node(p, first_interior), f32::NAN))),
        ("split", Box::new(move |p| craft::put_f32(p, node(p, first_interior), f32::INFINITY))),
        ("leaf", Box::new(move |p| craft::put_u32(p, node(p, first_leaf), u32::MAX - 1))),
        ("leaf", Box::new(move |p| craft::put_u32(p, node(p, first_leaf) + 4, 3 | (1 << 29)))),
        (
            "triangle index",
            Box::new(|p| {
                let at = craft::section_offset(p, 5);
                craft::put_u32(p, at, 1 << 20)
            }),
        ),
        (
            "material",
            Box::new(|p| {
                let at = craft::section_offset(p, 1);
                craft::put_u32(p, at, 77)
            }),
        ),
        (
            "light",
            Box::new(|p| {
                let at = craft::section_offset(p, 1);
                craft::put_u32(p, at + 4, 5)
            }),
        ),
        (
            "pointing back",
            Box::new(|p| {
                let at = craft::section_offset(p, 3);
                craft::put_u32(p, at, 1 << 30)
            }),
        ),
        (
            "cdf",
            Box::new(|p| {
                let at = craft::section_offset(p, 3);
                craft::put_f32(p, at + 8, 2.0)
            }),
        ),
        ("vertex", Box::new(|p| craft::put_f32(p, 4, f32::INFINITY))),
        (
            "kind",
            Box::new(|p| {
                let at = craft::section_offset(p, 2);
                craft::put_u32(p, at, 7)
            }),
        ),
        (
            "colours",
            Box::new(|p| {
                let at = craft::section_offset(p, 2);
                craft::put_f32(p, at + 16, -1.0)
            }),
        ),
        ("counts need", Box::new(|p| p.header["counts"]["triangles"] = serde_json::json!(1u64 << 40))),
        ("overflows", Box::new(|p| p.header["counts"]["indices"] = serde_json::json!(u64::MAX))),
        ("counts need", Box::new(|p| p.header["counts"]["nodes"] = serde_json::json!(0))),
        ("material names", Box::new(|p| p.header["material_names"] = serde_json::json!(["only one"]))),
        ("bounds", Box::new(|p| p.header["tree_bounds"] = serde_json::json!([[1, 1, 1], [0, 0, 0]]))),
        ("header", Box::new(|p| p.header["build_settings"] = serde_json::json!("fast"))),
        ("header", Box::new(|p| p.header["surprise"] = serde_json::json!(1))),
    ];
    for (i, (needle, edit)) in cases.iter().enumerate() {
        let mut p = craft::split(&bytes);
        edit(&mut p);
        let crafted = craft::join(&p);
        let e = match kdc::decode(Path::new("crafted.kdc"), &crafted) {
            Ok(_) => panic!("case {i} ({needle}) accepted"),
            Err(e) => format!("{e:#}"),
        };
        assert!(e.contains("crafted.kdc") && e.contains(needle), "case {i}: {e:?} lacks {needle:?}");
    }
    // The untouched pieces put together again are accepted: the edits are what is refused.
    assert!(kdc::decode(Path::new("ok.kdc"), &craft::join(&craft::split(&bytes))).is_ok());
}
