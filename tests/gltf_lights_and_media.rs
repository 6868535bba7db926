//! glTF lights and media end to end, on glTF files the tests write: KHR_lights_punctual lights
//! against analytic irradiance, KHR_materials_volume absorption against Beer–Lambert through a
//! slab, and alphaMode BLEND as stochastic transparency; the CPU and lavapipe agree bit for bit.
#[path = "common/gltf_files.rs"]
mod gltf_files;
use gltf_files::*;
use kdtrace::render::{cpu, gpu, Rendered};
use kdtrace::settings::{Aov, RenderSettings, SceneSettings};
use kdtrace::Loaded;
use shared::glam::DVec3;
use std::path::Path;

/// KHR_lights_punctual: a point light 1 above the quad's centre, a directional light tilted 60°
/// by its node's rotation and a spot light render the radiance the quad's BSDF gives their
/// analytic irradiance (I/d², E·cos θ; direct light only, at the centre pixel); a spot turned
/// away leaves the quad black; a scene file's placement moves the file's light with its mesh.
#[test]
fn punctual_lights_light_the_quad_as_their_nodes_place_them() {
    let dir = folder("lights");
    // The quad's value f(wo = +z, wi) · cos θ_i, from its own material.
    let radiance = |l: &Loaded, wi: shared::glam::Vec3| {
        let m = l.compiled.scene.materials[0];
        let z = shared::glam::Vec3::Z;
        let (f, _) = shared::material::eval(shared::features::Variant::GENERIC_SPEC, &m, &[], z, z, wi, true);
        f * wi.z
    };
    let centre = |path: &Path| {
        let l = load(path, None);
        let s = settings(&l, SceneSettings { bounces: Some(0), ..small(15, 15, 64) });
        let r = cpu::render(&l.compiled, &s, &none).unwrap();
        (l, pixel(&r, 7, 7))
    };
    let tilt = (30f64.to_radians().sin(), 30f64.to_radians().cos());
    let cases: [(&str, String, String, f32); 3] = [
        (
            "point",
            r#"{"type": "point", "color": [1, 0.5, 0.25], "intensity": 2}"#.into(),
            r#""translation": [0, 0, 1]"#.into(),
            2.0,
        ),
        (
            // Rotated 60° about x, the light travels along (0, sin 60°, −cos 60°).
            "directional",
            r#"{"type": "directional", "color": [1, 0.5, 0.25], "intensity": 3}"#.into(),
            format!(r#""rotation": [{}, 0, 0, {}]"#, tilt.0, tilt.1),
            3.0,
        ),
        (
            "spot",
            r#"{"type": "spot", "color": [1, 0.5, 0.25], "intensity": 2, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.3}}"#
                .into(),
            r#""translation": [0, 0, 1]"#.into(),
            2.0,
        ),
    ];
    for (name, light, node, intensity) in &cases {
        let path = dir.join(format!("{name}.gltf"));
        std::fs::write(&path, lit_quad_gltf(light, node)).unwrap();
        let (l, got) = centre(&path);
        assert_eq!(l.compiled.scene.punctual_lights.len(), 1, "{name}");
        let (wi, irradiance) = if *name == "directional" {
            let a = 60f32.to_radians();
            (shared::glam::Vec3::new(0.0, -a.sin(), a.cos()), *intensity)
        } else {
            (shared::glam::Vec3::Z, *intensity)
        };
        let want = radiance(&l, wi) * irradiance * shared::glam::Vec3::new(1.0, 0.5, 0.25);
        for k in 0..3 {
            assert!((got[k] - want[k]).abs() <= 0.02 * want[k], "{name}: {got:?}, want {want:?}");
        }
    }
    // A spot turned away (180° about x: it shines along +z) lights nothing.
    let path = dir.join("away.gltf");
    std::fs::write(&path, lit_quad_gltf(&cases[2].1, r#""translation": [0, 0, 1], "rotation": [1, 0, 0, 0]"#)).unwrap();
    assert_eq!(centre(&path).1, [0.0; 3], "a spot turned away");
    // Placed 5 up by a scene file, the point light moves with the quad.
    std::fs::write(dir.join("point.toml"), "[[mesh]]\nfile = \"point.gltf\"\ntranslate = [0, 5, 0]\n").unwrap();
    let l = load(&dir.join("point.toml"), None);
    let light = l.compiled.scene.punctual_lights[0];
    let world = light.position + l.compiled.origin;
    assert!((world - DVec3::new(0.0, 5.0, 1.0)).length() < 1e-5, "{world:?}");
}

/// KHR_materials_clearcoat: a coat of factor 0.8 and roughness 0.6 over a dark quad, lit by
/// a point light 1 above its centre and seen from above, adds c·F(0°)·D(0)·G1²/4 · E and leaves
/// 1 − c·F(0°) of the uncoated quad's radiance (F(0°) = 0.04 for index 1.5, D(0) = 1/(πα²),
/// G1 = 1 at normal incidence: worked out here in f64, not by the renderer's code); a
/// clearcoatTexture of red 128 scales c by 128/255. The CPU and lavapipe agree bit for bit; the
/// coat's roughness texture is named in a warning, not read; the extension may be required.
#[test]
fn clear_coats_reflect_over_the_base() {
    let dir = folder("clearcoat");
    let light = r#"{"type": "point", "color": [1, 0.5, 0.25], "intensity": 2}"#;
    let dark = r#""pbrMetallicRoughness": {"baseColorFactor": [0.05, 0.05, 0.05, 1], "metallicFactor": 0, "roughnessFactor": 1}"#;
    let coat = |texture: &str| {
        format!(
            r#""extensions": {{"KHR_materials_clearcoat": {{"clearcoatFactor": 0.8, "clearcoatRoughnessFactor": 0.6,
               "clearcoatRoughnessTexture": {{"index": 0}}{texture}}}}}"#
        )
    };
    // A 1×1 PNG of red 128 as the file's texture 0.
    let mut png = Vec::new();
    image::RgbaImage::from_pixel(1, 1, image::Rgba([128, 0, 0, 255]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let images = format!(
        r#""textures": [{{"source": 0}}], "images": [{{"uri": "data:image/png;base64,{}"}}], "materials": ["#,
        b64(&png)
    );
    let centre = |name: &str, material: String| {
        let path = dir.join(format!("{name}.gltf"));
        let file = lit_quad_gltf_with(light, r#""translation": [0, 0, 1]"#, &material)
            .replacen(r#""materials": ["#, &images, 1)
            .replacen(
                r#""extensionsUsed": ["#,
                r#""extensionsRequired": ["KHR_materials_clearcoat"], "extensionsUsed": ["#,
                1,
            );
        std::fs::write(&path, file).unwrap();
        let l = load(&path, None);
        let s = settings(&l, SceneSettings { bounces: Some(0), ..small(31, 31, 64) });
        let r = cpu::render(&l.compiled, &s, &none).unwrap();
        (l, s, r)
    };
    let (_, _, bare) = centre("bare", format!("{{{dark}}}"));
    let (l, s, coated) = centre("coated", format!("{{{dark}, {}}}", coat("")));
    let (lt, _, textured) =
        centre("textured", format!("{{{dark}, {}}}", coat(r#", "clearcoatTexture": {"index": 0}"#)));
    let m = l.compiled.scene.materials[0];
    assert_eq!((m.eta.x, m.eta.y), (0.8, 0.6f32 * 0.6), "the coat's factor and α");
    assert_eq!(m.textures[shared::layout::TEXTURE_CLEARCOAT], shared::layout::NO_TEXTURE);
    assert_ne!(lt.compiled.scene.materials[0].textures[shared::layout::TEXTURE_CLEARCOAT], shared::layout::NO_TEXTURE);
    assert!(
        l.warnings.iter().any(|n| n.contains("clearcoatRoughnessTexture ignored")),
        "no warning for the coat's roughness texture: {:?}",
        l.warnings
    );
    let (alpha, f0) = (0.36f64, 0.04f64);
    let b = pixel(&bare, 15, 15);
    for (c, image, what) in [(0.8f64, &coated, "factor"), (0.8 * 128.0 / 255.0, &textured, "texture")] {
        let coat_value = c * f0 / (std::f64::consts::PI * alpha * alpha) / 4.0;
        let got = pixel(image, 15, 15);
        for (k, colour) in [1.0f64, 0.5, 0.25].into_iter().enumerate() {
            let want = coat_value * 2.0 * colour + (1.0 - c * f0) * b[k] as f64;
            let got = got[k] as f64;
            assert!((got - want).abs() <= 0.02 * want, "{what}, channel {k}: {got}, want {want} (uncoated {})", b[k]);
            assert!(got > 1.5 * b[k] as f64, "{what}, channel {k}: the coat adds little: {got} against {}", b[k]);
        }
    }
    let s = RenderSettings { spp: 8, ..s };
    let g = gpu::Gpu::lavapipe().unwrap();
    let (a, b) = (cpu::render(&lt.compiled, &s, &none).unwrap(), g.render(&lt.compiled, &s, &none).unwrap());
    assert!(bits(&a) == bits(&b), "lavapipe's image of the coated quad differs from the CPU's");
}

/// KHR_materials_volume: a slab 0.5 thick whose medium keeps (0.5, 0.8, 1) of the light over a
/// distance of 1 lets a = e^(−σ·0.5) = (0.707, 0.894, 1) through per crossing. Under a sky of 1,
/// seen at normal incidence, the slab shows its reflection F plus what crosses it, reflected
/// inside any number of times: F + (1 − F)²·a / (1 − F·a), F = 0.04 for index 1.5 (the clear
/// slab shows 1). The CPU (its lane integrator) and lavapipe agree bit for bit.
#[test]
fn volumes_absorb_by_beer_lambert() {
    let dir = folder("volume");
    let render = |name: &str, volume: &str, gpu: Option<&gpu::Gpu>| {
        let path = dir.join(format!("{name}.gltf"));
        std::fs::write(&path, slab_gltf(volume)).unwrap();
        let l = load(&path, None);
        let s = settings(&l, SceneSettings { environment: Some([1.0; 3]), bounces: Some(6), ..small(3, 3, 4096) });
        let r = cpu::render(&l.compiled, &s, &none).unwrap();
        if let Some(g) = gpu {
            // The CPU's lane integrator against lavapipe's scalar one.
            assert!(cpu::runs_lanes(&s), "{name}: the CPU must run the lane integrator");
            // Fewer samples on lavapipe: a dispatch holds one 8-sample block.
            let s = RenderSettings { spp: 64, ..s };
            let (a, b) = (cpu::render(&l.compiled, &s, &none).unwrap(), g.render(&l.compiled, &s, &none).unwrap());
            assert!(bits(&a) == bits(&b), "{name}: lavapipe's image differs from the CPU's");
        }
        (l, pixel(&r, 1, 1))
    };
    let (clear_scene, clear) = render("clear", "", None);
    assert_eq!(clear_scene.compiled.scene.materials[0].k.truncate(), shared::glam::Vec3::ZERO);
    let g = gpu::Gpu::lavapipe().unwrap();
    let volume = r#""thicknessFactor": 0.5, "attenuationDistance": 1, "attenuationColor": [0.5, 0.8, 1]"#;
    let (_, tinted) = render("tinted", volume, Some(&g));
    assert!(clear.iter().all(|&c| (c - 1.0).abs() < 1e-3), "the clear slab shows the sky: {clear:?}");
    let f = 0.04f32;
    for (k, keep) in [0.5f32, 0.8, 1.0].into_iter().enumerate() {
        let a = keep.powf(0.5);
        let want = f + (1.0 - f) * (1.0 - f) * a / (1.0 - f * a);
        assert!((tinted[k] - want).abs() < 4e-3, "channel {k}: {}, want {want}", tinted[k]);
    }
}

/// alphaMode BLEND is stochastic transparency: a camera ray passes the surface with probability
/// 1 − alpha, so the albedo image (black where nothing is hit) shows alpha × the albedo on
/// average: the textured quad's top left quadrant of alpha 0.4 (its texture's), a grey quad of
/// constant alpha 0.3 (its factor's). Under a sky, lavapipe renders the same bits as the CPU.
#[test]
fn blend_is_stochastic_transparency() {
    let dir = folder("blend");
    let mean_of = |r: &Rendered, xs: std::ops::Range<usize>, ys: std::ops::Range<usize>| {
        let mut sum = [0f32; 3];
        let n = (xs.len() * ys.len()) as f32;
        for y in ys {
            for x in xs.clone() {
                let p = pixel(r, x, y);
                (0..3).for_each(|k| sum[k] += p[k] / n);
            }
        }
        sum
    };
    let textured = dir.join("textured.gltf");
    let png = png_quadrants_alpha(102);
    std::fs::write(&textured, quad_gltf_with(r#""name": "q""#, "[0, 0, 3]", "", 4, r#""alphaMode": "BLEND", "#, &png))
        .unwrap();
    let l = load(&textured, None);
    let s = RenderSettings { aov: Aov::Albedo, ..settings(&l, small(16, 16, 256)) };
    let r = cpu::render(&l.compiled, &s, &none).unwrap();
    let (got, full) = (mean_of(&r, 2..6, 2..6), linear(QUADRANTS[0]));
    for k in 0..3 {
        let want = 0.4 * full[k];
        assert!((got[k] - want).abs() <= 0.05 * full[k] + 1e-3, "textured: {got:?}, want 0.4 × {full:?}");
    }
    assert!(close(mean_of(&r, 10..14, 10..14), linear(QUADRANTS[3])), "the opaque quadrant");
    let lit = settings(&l, SceneSettings { environment: Some([1.0; 3]), bounces: Some(2), ..small(12, 12, 8) });
    let g = gpu::Gpu::lavapipe().unwrap();
    let (a, b) = (cpu::render(&l.compiled, &lit, &none).unwrap(), g.render(&l.compiled, &lit, &none).unwrap());
    assert!(bits(&a) == bits(&b), "lavapipe's image differs from the CPU's");

    let constant = dir.join("constant.gltf");
    let material = r#"{"alphaMode": "BLEND", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 0.3], "metallicFactor": 0}}"#;
    std::fs::write(
        &constant,
        lit_quad_gltf_with(r#"{"type": "point", "intensity": 1}"#, r#""translation": [0, 0, 1]"#, material),
    )
    .unwrap();
    let l = load(&constant, None);
    let s = RenderSettings { aov: Aov::Albedo, ..settings(&l, small(16, 16, 256)) };
    let got = mean_of(&cpu::render(&l.compiled, &s, &none).unwrap(), 4..12, 4..12);
    for k in 0..3 {
        assert!((got[k] - 0.15).abs() <= 0.01, "constant alpha 0.3 over albedo 0.5: {got:?}");
    }
}
