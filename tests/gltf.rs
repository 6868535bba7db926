//! glTF 2.0 import end to end: the Khronos samples in `tests/data/gltf` (each loads and renders
//! without NaN on the CPU and on lavapipe, bit for bit the same; texture coordinates, texture
//! transforms, emissive strengths and cameras show what they should), glTF files written here
//! (a textured quad as a data URI: v runs top to bottom; a node at survey coordinates; strips
//! and fans; a scene file placing a glTF, exported and compiled), and the `--camera` flag.
#[path = "common/gltf_files.rs"]
mod gltf_files;
#[path = "common/run.rs"]
mod run;
use base64::Engine;
use gltf_files::*;
use kdtrace::kdbuild::BuildSettings;
use kdtrace::render::load::load_with_camera;
use kdtrace::render::{cpu, gpu, Compiled};
use kdtrace::scene::EnvironmentMap;
use kdtrace::settings::{Aov, RenderSettings, SceneSettings};
use kdtrace::Loaded;
use shared::glam::DVec3;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Every sample loads and renders without NaN or Inf, the same bits on the CPU and lavapipe:
/// the albedo and normal images (texture lookups, UVs, normals, cut-outs, cameras) and radiance
/// under a constant sky, in the dark (the samples' own emitters) and, for a textured and a
/// metal sample, under an environment map.
#[test]
fn every_sample_renders_on_the_cpu_and_lavapipe_alike() {
    let g = gpu::Gpu::lavapipe().unwrap();
    for file in [
        "Cameras/Cameras.gltf",
        "TextureCoordinateTest/TextureCoordinateTest.gltf",
        "TextureTransformTest/TextureTransformTest.gltf",
        "EmissiveStrengthTest/EmissiveStrengthTest.gltf",
        "MetalRoughSpheresNoTextures/MetalRoughSpheresNoTextures.gltf",
        "TransmissionTest/TransmissionTest.gltf",
    ] {
        let l = load(&data(file), None);
        let lit =
            settings(&l, SceneSettings { environment: Some([0.8, 0.9, 1.0]), bounces: Some(3), ..small(20, 20, 2) });
        let dark = RenderSettings { environment: shared::glam::Vec3::ZERO, ..lit };
        // Under a map: two samples (a pipeline compile each on lavapipe), textured and metal.
        let mut mapped = load(&data(file), None).compiled;
        mapped.scene.environment_map = Some(sky_map());
        mapped.prepare_emitters();
        let with_map = file.starts_with("TextureTransformTest") || file.starts_with("MetalRough");
        for (what, c, s) in [
            ("albedo", &l.compiled, RenderSettings { aov: Aov::Albedo, ..lit }),
            ("normal", &l.compiled, RenderSettings { aov: Aov::Normal, ..lit }),
            ("dark radiance", &l.compiled, dark),
            ("lit radiance", &l.compiled, lit),
            ("radiance under a map", &mapped, dark),
        ] {
            if what == "radiance under a map" && !with_map {
                continue;
            }
            let a = cpu::render(c, &s, &none).unwrap();
            assert!(a.sum.iter().chain(&a.sum_sq).all(|p| p.is_finite()), "{file} {what}: NaN or Inf on the CPU");
            if what != "dark radiance" {
                assert!(a.mean().iter().flatten().any(|&v| v > 0.0), "{file} {what}: a black image");
            }
            let b = g.render(c, &s, &none).unwrap();
            assert!(bits(&a) == bits(&b), "{file} {what}: lavapipe's image differs from the CPU's");
        }
    }
}

/// A small sky: brighter overhead, with a bright patch, rotated off the axes.
fn sky_map() -> EnvironmentMap {
    let (w, h) = (16u32, 8u32);
    let texels = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let b = if (x, y) == (5, 2) { 30.0 } else { 0.2 + 0.15 * (h - y) as f32 + 0.03 * x as f32 };
            [b, 0.9 * b, 0.7 * b]
        })
        .collect();
    EnvironmentMap::new(w, h, texels, 1.0, [0.0, 40.0, 0.0], "sky".into()).unwrap()
}

/// TextureCoordinateTest: each quad shows its colour (baseColorFactor × the white template) and
/// its corner label upright, in the upper part of the top quads: v runs top to bottom in glTF.
#[test]
fn texture_coordinate_test_shows_each_corner_upright() {
    let l = load(&data("TextureCoordinateTest/TextureCoordinateTest.gltf"), None);
    let s = RenderSettings { aov: Aov::Albedo, ..settings(&l, small(128, 128, 4)) };
    let r = cpu::render(&l.compiled, &s, &none).unwrap();
    let mean = r.mean();
    let block = |x0: usize, y0: usize, w: usize, h: usize| -> [f32; 3] {
        let mut sum = [0.0; 3];
        for y in y0..y0 + h {
            for x in x0..x0 + w {
                for k in 0..3 {
                    sum[k] += mean[y * 128 + x][k] / (w * h) as f32;
                }
            }
        }
        sum
    };
    // Blank template areas of each quad: the factor's colour (texel white = 1).
    for (name, (x, y), want) in [
        ("top left", (24, 28), [0.8, 0.8, 0.0]),
        ("top right", (100, 28), [0.8, 0.08, 0.0]),
        ("bottom left", (24, 96), [0.0, 0.16, 0.8]),
        ("bottom right", (100, 96), [0.0, 0.8, 0.0]),
    ] {
        let got = block(x, y, 4, 4);
        for k in 0..3 {
            assert!((got[k] - want[k]).abs() < 0.02, "{name}: {got:?}, want {want:?}");
        }
    }
    // The label "Top Left" (dark text) lies in the quad's upper part; read upside down it would
    // lie as far from the quad's bottom edge.
    let sum = |c: [f32; 3]| c[0] + c[1] + c[2];
    let label = sum(block(16, 14, 20, 5));
    let mirrored = sum(block(16, 31, 20, 5));
    assert!(label < 0.9 * mirrored, "label band {label}, mirrored band {mirrored}");
}

/// TextureTransformTest: the offset row shows the U, V and UV quadrants of UV.png (green, blue,
/// cyan), which only the offsets bring into view.
#[test]
fn texture_transform_test_offsets_show_their_quadrants() {
    let l = load(&data("TextureTransformTest/TextureTransformTest.gltf"), None);
    let s = RenderSettings { aov: Aov::Albedo, ..settings(&l, small(96, 96, 4)) };
    let r = cpu::render(&l.compiled, &s, &none).unwrap();
    // Each square's upper left area (clear of its letter and tick).
    let at = |x: f64| {
        let (px, py) = project(&s, DVec3::new(x - 0.3, 0.55 + 0.3, 0.0));
        pixel(&r, px, py)
    };
    let (u, v, uv) = (at(-1.1), at(0.0), at(1.1));
    assert!(u[1] > 2.0 * u[0] && u[1] > 2.0 * u[2], "offset U: {u:?} is not green");
    assert!(v[2] > 2.0 * v[0] && v[2] > 2.0 * v[1], "offset V: {v:?} is not blue");
    assert!(uv[1] > 2.0 * uv[0] && uv[2] > 2.0 * uv[0], "offset UV: {uv:?} is not cyan");
}

/// EmissiveStrengthTest: the five cubes' radiance follows their strengths 1, 2, 4, 8, 16.
#[test]
fn emissive_strengths_scale_the_radiance() {
    let l = load(&data("EmissiveStrengthTest/EmissiveStrengthTest.gltf"), None);
    let s = RenderSettings { max_bounces: 0, ..settings(&l, small(96, 32, 4)) };
    let r = cpu::render(&l.compiled, &s, &none).unwrap();
    let blue: Vec<f32> = [-6.0, -3.0, 0.0, 3.0, 6.0]
        .iter()
        .map(|&x| {
            let (px, py) = project(&s, DVec3::new(x, 0.0, 0.0));
            pixel(&r, px, py)[2]
        })
        .collect();
    for (i, b) in blue.iter().enumerate() {
        let want = 0.9 * (1 << i) as f32;
        assert!((b / want - 1.0).abs() < 0.05, "cube {i}: blue {b}, want about {want} ({blue:?})");
    }
}

/// Cameras: camera 0 (perspective) is the default and places the eye at its node; camera 1 is
/// orthographic and refused by name; the file's camera gives another view than the framing.
#[test]
fn cameras_are_chosen_by_index_or_refused() {
    let path = data("Cameras/Cameras.gltf");
    let first = load(&path, None);
    let zero = load(&path, Some("0"));
    assert_eq!(first.settings, zero.settings);
    let s = &zero.settings;
    assert_eq!(s.eye, Some([0.5, 0.5, 3.0]));
    assert_eq!(s.target, Some([0.5, 0.5, 2.0]));
    assert!((s.fov_deg.unwrap() - 0.7f32.to_degrees()).abs() < 1e-4);
    assert_eq!((s.width, s.height), (Some(512), Some(512)));
    let e = load_with_camera(&path, BuildSettings::default(), Some("1")).err().unwrap().to_string();
    assert!(e.contains("Cameras.gltf") && e.contains("camera 1") && e.contains("orthographic"), "{e}");
    let e = load_with_camera(&path, BuildSettings::default(), Some("nope")).err().unwrap().to_string();
    assert!(e.contains("no camera \"nope\""), "{e}");
    // The file's camera against the default framing (the scene without its cameras' settings).
    let s = RenderSettings { aov: Aov::Albedo, ..settings(&zero, small(16, 16, 1)) };
    let own = cpu::render(&zero.compiled, &s, &none).unwrap();
    let (lo, hi) = zero.compiled.world_bounds();
    let framed = RenderSettings { camera: SceneSettings::default().resolve(lo, hi).unwrap().camera, ..s };
    let other = cpu::render(&zero.compiled, &framed, &none).unwrap();
    assert!(bits(&own) != bits(&other));
    // The CLI: --width alone keeps the camera's aspect ratio (1 here: 64 × 64, not 64 × 512).
    let dir = folder("cameras-cli");
    let out = dir.join("aspect.png");
    let o = Command::new(env!("CARGO_BIN_EXE_kdtrace"))
        .args(["render", path.to_str().unwrap(), "--width", "64", "--spp", "1", "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(image::image_dimensions(&out).unwrap(), (64, 64));
    // An orthographic camera and --camera on an OBJ exit with 2 and say why.
    for (scene, camera, needle) in [
        (path.clone(), "1", "orthographic"),
        (PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-box.obj"), "0", "--camera"),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_kdtrace"))
            .args(["render", scene.to_str().unwrap(), "--camera", camera, "--spp", "1", "--out"])
            .arg(dir.join("x.png"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(needle), "{err}");
    }
}

// ---- glTF files written here ----

/// The image's top row (v = 0 in glTF) appears at the top, in triangles, strips and fans alike;
/// a KHR_texture_transform offset of half the image in u swaps the left and right quadrants.
#[test]
fn a_textured_quad_is_upright_in_every_primitive_mode_and_transforms() {
    let dir = folder("quad");
    for mode in [4, 5, 6] {
        let path = dir.join(format!("quad{mode}.gltf"));
        std::fs::write(&path, quad_gltf(r#""name": "q""#, "[0, 0, 3]", "", mode)).unwrap();
        let got = quadrant_albedo(&path);
        for q in 0..4 {
            assert!(close(got[q], linear(QUADRANTS[q])), "mode {mode}, quadrant {q}: {:?}", got[q]);
        }
    }
    let path = dir.join("offset.gltf");
    let t = r#", "extensions": {"KHR_texture_transform": {"offset": [0.5, 0]}}"#;
    std::fs::write(&path, quad_gltf(r#""name": "q""#, "[0, 0, 3]", t, 4)).unwrap();
    let got = quadrant_albedo(&path);
    for (q, want) in [1, 0, 3, 2].into_iter().enumerate() {
        assert!(close(got[q], linear(QUADRANTS[want])), "offset: quadrant {q}: {:?}", got[q]);
    }
}

/// KHR_mesh_quantization: the textured quad with its positions as normalised i16 (±32767 for ±1)
/// or as plain i16 (±1), and its texture coordinates as normalised u16, renders the same bits as
/// with f32 attributes; the extension may be required.
#[test]
fn quantized_attributes_render_as_floats() {
    let dir = folder("quantized");
    let float = dir.join("float.gltf");
    std::fs::write(&float, quad_gltf(r#""name": "q""#, "[0, 0, 3]", "", 4)).unwrap();
    let l = load(&float, None);
    let s = RenderSettings { aov: Aov::Albedo, ..settings(&l, small(16, 16, 4)) };
    let want = bits(&cpu::render(&l.compiled, &s, &none).unwrap());
    for (what, one, normalized) in [("normalised i16", 32767i16, true), ("plain i16", 1, false)] {
        let mut buf = Vec::new();
        for p in [[-1i16, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]] {
            // Each position padded to 8 bytes: vertex strides are multiples of 4.
            for c in p.into_iter().chain([0]) {
                buf.extend((c * one).to_le_bytes());
            }
        }
        for uv in [[0u16, 65535], [65535, 65535], [65535, 0], [0, 0]].iter().flatten() {
            buf.extend(uv.to_le_bytes());
        }
        for i in [0u16, 1, 2, 0, 2, 3] {
            buf.extend(i.to_le_bytes());
        }
        let file = quad_gltf(r#""name": "q""#, "[0, 0, 3]", "", 4)
            .replace(
                r#""extensionsUsed": ["KHR_texture_transform"],"#,
                r#""extensionsUsed": ["KHR_mesh_quantization"], "extensionsRequired": ["KHR_mesh_quantization"],"#,
            )
            .replace(
                r#"{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, -1, 0], "max": [1, 1, 0]}"#,
                &format!(
                    r#"{{"bufferView": 0, "componentType": 5122, "normalized": {normalized}, "count": 4, "type": "VEC3", "min": [-{one}, -{one}, 0], "max": [{one}, {one}, 0]}}"#
                ),
            )
            .replace(
                r#"{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}"#,
                r#"{"bufferView": 1, "componentType": 5123, "normalized": true, "count": 4, "type": "VEC2"}"#,
            )
            .replace(
                r#"{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 32},"#,
                r#"{"buffer": 0, "byteOffset": 0, "byteLength": 32, "byteStride": 8}, {"buffer": 0, "byteOffset": 32, "byteLength": 16},"#,
            )
            .replace(r#""byteOffset": 80"#, r#""byteOffset": 48"#);
        let file = {
            // The new buffer, in place of the f32 one.
            let start = file.find("octet-stream;base64,").unwrap() + "octet-stream;base64,".len();
            let data_uri_end = start + file[start..].find('"').unwrap();
            let with_data = format!("{}{}{}", &file[..start], b64(&buf), &file[data_uri_end..]);
            let len_at = with_data.find(r#""byteLength": "#).unwrap();
            let len_end = len_at + with_data[len_at..].find(',').unwrap();
            format!("{}\"byteLength\": {}{}", &with_data[..len_at], buf.len(), &with_data[len_end..])
        };
        assert!(file.contains("5122") && file.contains("5123, \"normalized\""), "{what}: the file was not rewritten");
        let path = dir.join(format!("{}.gltf", what.replace(' ', "-")));
        std::fs::write(&path, file).unwrap();
        let l = load(&path, None);
        let got = bits(&cpu::render(&l.compiled, &s, &none).unwrap());
        assert!(got == want, "{what}: the quantized quad renders differently");
    }
}

/// alphaMode MASK cuts out where the base colour's alpha is below alphaCutoff (the top left
/// quadrant's alpha is 0.4): the camera sees through it (black albedo, a miss) at the default
/// cutoff 0.5, not at 0.3; BLEND is rendered as MASK at 0.5.
#[test]
fn alpha_masks_cut_out_below_the_cutoff() {
    let dir = folder("alpha");
    for (material, cut) in
        [(r#""alphaMode": "MASK", "#, true), (r#""alphaMode": "MASK", "alphaCutoff": 0.3, "#, false), ("", false)]
    {
        let path = dir.join("alpha.gltf");
        let png = png_quadrants_alpha(102);
        std::fs::write(&path, quad_gltf_with(r#""name": "q""#, "[0, 0, 3]", "", 4, material, &png)).unwrap();
        let got = quadrant_albedo(&path);
        let want = if cut { [0.0; 3] } else { linear(QUADRANTS[0]) };
        assert!(close(got[0], want), "{material}: top left {:?}", got[0]);
        assert!(close(got[3], linear(QUADRANTS[3])), "{material}: bottom right {:?}", got[3]);
    }
}

/// A normal map (normalTexture) bends the shading normal in the frame of the texture
/// coordinates: its red channel toward +u (here +x), its green toward the image's top (+y here,
/// glTF's −v), scaled by `scale`; the normal image is the same bits on the CPU and lavapipe.
#[test]
fn normal_maps_bend_the_shading_normal() {
    let dir = folder("normal-map");
    let g = gpu::Gpu::lavapipe().unwrap();
    for (rgb, scale, want) in [
        ([204u8, 128, 230], 1.0, [0.6, 0.0, 0.8]),
        ([128, 204, 230], 1.0, [0.0, 0.6, 0.8]),
        ([128, 52, 230], 1.0, [0.0, -0.6, 0.8]),
        ([204, 128, 230], 0.5, [0.3, 0.0, 0.8]),
        ([128, 128, 255], 1.0, [0.0, 0.0, 1.0]),
    ] {
        let mut json: serde_json::Value =
            serde_json::from_str(&quad_gltf(r#""name": "q""#, "[0, 0, 3]", "", 4)).unwrap();
        let img = image::RgbaImage::from_pixel(4, 4, image::Rgba([rgb[0], rgb[1], rgb[2], 255]));
        let mut png = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).unwrap();
        json["images"]
            .as_array_mut()
            .unwrap()
            .push(serde_json::json!({"uri": format!("data:image/png;base64,{}", b64(&png))}));
        json["textures"].as_array_mut().unwrap().push(serde_json::json!({"source": 1}));
        json["materials"][0]["normalTexture"] = serde_json::json!({"index": 1, "scale": scale});
        let path = dir.join("n.gltf");
        std::fs::write(&path, serde_json::to_string(&json).unwrap()).unwrap();
        let l = load(&path, None);
        let s = RenderSettings { aov: Aov::Normal, ..settings(&l, small(8, 8, 1)) };
        let a = cpu::render(&l.compiled, &s, &none).unwrap();
        let b = g.render(&l.compiled, &s, &none).unwrap();
        assert!(bits(&a) == bits(&b), "{rgb:?}: lavapipe's normal image differs from the CPU's");
        let w = DVec3::from(want).normalize();
        let got = pixel(&a, 4, 4);
        for k in 0..3 {
            assert!((got[k] as f64 - w[k]).abs() < 0.02, "{rgb:?} × {scale}: normal {got:?}, want {w}");
        }
    }
}

/// A GLB (JSON and binary chunks, the image in a buffer view) loads as the same .gltf does.
#[test]
fn a_glb_renders_as_its_gltf() {
    let dir = folder("glb");
    let text = quad_gltf(r#""name": "q""#, "[0, 0, 3]", "", 4);
    let gltf = dir.join("quad.gltf");
    std::fs::write(&gltf, &text).unwrap();
    // The same file as GLB: the buffer's data URI becomes the BIN chunk, the image a buffer view
    // after it.
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let decode = |uri: &str| base64::engine::general_purpose::STANDARD.decode(uri.split_once(',').unwrap().1).unwrap();
    let mut bin = decode(json["buffers"][0]["uri"].as_str().unwrap());
    let png = decode(json["images"][0]["uri"].as_str().unwrap());
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let offset = bin.len();
    bin.extend(&png);
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    json["buffers"][0] = serde_json::json!({"byteLength": bin.len()});
    json["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"buffer": 0, "byteOffset": offset, "byteLength": png.len()}));
    json["images"][0] = serde_json::json!({"bufferView": 3, "mimeType": "image/png"});
    let mut chunk = serde_json::to_vec(&json).unwrap();
    while !chunk.len().is_multiple_of(4) {
        chunk.push(b' ');
    }
    let mut glb = Vec::new();
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend(((12 + 8 + chunk.len() + 8 + bin.len()) as u32).to_le_bytes());
    glb.extend((chunk.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&chunk);
    glb.extend((bin.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(&bin);
    let path = dir.join("quad.glb");
    std::fs::write(&path, glb).unwrap();
    let got = quadrant_albedo(&path);
    for q in 0..4 {
        assert!(close(got[q], linear(QUADRANTS[q])), "glb quadrant {q}: {:?}", got[q]);
    }
    let render = |p: &Path| {
        let l = load(p, None);
        bits(
            &cpu::render(
                &l.compiled,
                &settings(&l, SceneSettings { environment: Some([1.0; 3]), ..small(8, 8, 2) }),
                &none,
            )
            .unwrap(),
        )
    };
    assert!(render(&gltf) == render(&path));
}

/// A node at survey coordinates (a parent translated by 1e6 on every axis, with digits no f32
/// keeps, and the quad's node rotated under it), its camera moved with it: composed in f64 and
/// moved to the local frame, it renders as the same quad at the origin, bit for bit, on the CPU
/// and on lavapipe.
#[test]
fn a_node_at_survey_coordinates_renders_as_at_the_origin() {
    let dir = folder("survey");
    let scene = |shift: f64| {
        let t = format!("[{s}, {s}, {s}]", s = shift);
        let c = format!("[{}, {}, {}]", shift, shift, shift + 3.0);
        quad_gltf(&format!(r#""translation": {t}, "rotation": [0, 0, 0.38268343236509, 0.923879532511287]"#), &c, "", 4)
    };
    let origin = dir.join("origin.gltf");
    std::fs::write(&origin, scene(0.0)).unwrap();
    let far = dir.join("far.gltf");
    std::fs::write(&far, scene(1_000_000.0)).unwrap();
    let (a, b) = (load(&origin, None), load(&far, None));
    assert_eq!(b.compiled.origin, DVec3::splat(1_000_000.0));
    assert_eq!(a.compiled.scene.triangles.len(), b.compiled.scene.triangles.len());
    let s = |l: &Loaded| settings(l, SceneSettings { environment: Some([1.0; 3]), ..small(16, 16, 4) });
    let ra = cpu::render(&a.compiled, &s(&a), &none).unwrap();
    let rb = cpu::render(&b.compiled, &s(&b), &none).unwrap();
    assert!(bits(&ra) == bits(&rb), "the far scene renders differently");
    let g = gpu::Gpu::lavapipe().unwrap();
    let albedo = RenderSettings { aov: Aov::Albedo, ..s(&b) };
    let (cb, gb) = (cpu::render(&b.compiled, &albedo, &none).unwrap(), g.render(&b.compiled, &albedo, &none).unwrap());
    assert!(bits(&cb) == bits(&gb), "lavapipe differs from the CPU on the far scene");
    // An f32 translation (what the gltf crate itself reads) could not hold 1e6 + 0.1 exactly;
    // the f64 path keeps it.
    let fine = dir.join("fine.gltf");
    std::fs::write(&fine, scene(1_000_000.1)).unwrap();
    let c = load(&fine, None);
    let lo = c.compiled.world_bounds().0;
    assert!((lo.x - (1_000_000.1 - 2f64.sqrt())).abs() < 1e-6, "{lo}");
}

/// A scene file places a glTF as it places an OBJ; `export` and `compile` keep the image.
#[test]
fn scene_files_export_and_compile_carry_gltf_meshes() {
    let dir = folder("scene-file");
    std::fs::write(dir.join("quad.gltf"), quad_gltf(r#""name": "q""#, "[0, 0, 3]", "", 4)).unwrap();
    std::fs::write(
        dir.join("s.toml"),
        "environment = [1, 1, 1]\n[camera]\neye = [2, 0, 3]\ntarget = [2, 0, 0]\nwidth = 12\nheight = 12\n\
         [render]\nspp = 2\n[[mesh]]\nfile = \"quad.gltf\"\ntranslate = [2, 0, 0]\n",
    )
    .unwrap();
    let render = |scene: &Path| -> Vec<u32> {
        let l = load_with_camera(scene, BuildSettings::default(), None).unwrap();
        bits(&cpu::render(&l.compiled, &settings(&l, SceneSettings::default()), &none).unwrap())
    };
    let direct = render(&dir.join("s.toml"));
    run::export(&dir.join("s.toml"), &dir.join("exported.toml"));
    assert!(direct == render(&dir.join("exported.toml")));
    let o = Command::new(env!("CARGO_BIN_EXE_kdtrace"))
        .args(["compile", dir.join("s.toml").to_str().unwrap(), "--out", dir.join("s.kdc").to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(direct == render(&dir.join("s.kdc")));
    // A glTF exported keeps its own camera as the scene file's.
    let gltf = dir.join("quad.gltf");
    run::export(&gltf, &dir.join("from-gltf.toml"));
    let text = std::fs::read_to_string(dir.join("from-gltf.toml")).unwrap();
    assert!(text.contains("quad.gltf") && text.contains("eye = [0.0, 0.0, 3.0]"), "{text}");
    let _: &Compiled = &load(&gltf, None).compiled;
}
