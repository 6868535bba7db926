//! Environment maps and punctual lights against closed forms: a white diffuse sphere in a
//! constant map of radiance 1 (a furnace: 1 everywhere), a point light, a spot's cone and a
//! directional light over a diffuse plane (radiance albedo/π · E·cos θ), the light-selection
//! distribution by power, and the scene-file forms with their errors.
#[path = "common/paths.rs"]
mod paths;
use kdtrace::{
    compile,
    kdbuild::BuildSettings,
    render::{cpu, gpu, Compiled, Rendered},
    scene::{diffuse, procedural, EnvironmentMap, PunctualLight, Scene},
    settings::{camera::Camera, RenderSettings},
};
use shared::glam::{DVec3, Vec3};
use shared::layout::LIGHT_NOT_TRIANGLE;
use std::f64::consts::PI;

fn no_progress(_: u64, _: u64) {}

fn settings(size: u32, spp: u32, bounces: u32, camera: Camera) -> RenderSettings {
    RenderSettings {
        width: size,
        height: size,
        spp,
        max_bounces: bounces,
        seed: 3,
        rr_start: 3,
        ..RenderSettings::with_camera(camera)
    }
}

/// A white (albedo 1) diffuse icosphere of radius 1 at the origin.
fn white_sphere() -> Scene {
    let tris = procedural::icosphere(3);
    let n = tris.len();
    Scene::new(tris, vec![0; n], vec![diffuse(Vec3::ONE, Vec3::ZERO)], vec!["white".into()]).unwrap()
}

#[test]
fn white_sphere_in_a_constant_map_is_a_furnace() {
    let mut c = compile(white_sphere(), BuildSettings::default());
    c.scene.environment_map = Some(EnvironmentMap::constant(16, 8, [1.0; 3]));
    c.prepare_emitters();
    let camera = Camera { eye: DVec3::new(0.3, 0.5, 3.5), target: DVec3::ZERO, up: DVec3::Y, fov_deg: 40.0 };
    let s = settings(24, 64, 3, camera);
    let r = cpu::render(&c, &s, &no_progress).unwrap();
    let m = r.mean();
    let mean = m.iter().map(|p| (p[0] + p[1] + p[2]) as f64 / 3.0).sum::<f64>() / m.len() as f64;
    assert!((mean - 1.0).abs() < 0.01, "furnace mean {mean}");
    for (i, p) in m.iter().enumerate() {
        for ch in p {
            assert!((ch - 1.0).abs() < 0.1, "pixel {i}: {p:?}");
        }
    }
    // Rays that miss the sphere see exactly 1; the sphere fills the middle.
    assert_eq!(m[0], [1.0; 3]);
    assert_eq!(r.zeroed_samples(), 0);
}

/// A diffuse floor quad at y = 0 (albedo `a`), 40 units on a side, seen from straight above.
fn floor(albedo: f32) -> Compiled {
    let q = procedural::quad(
        Vec3::new(-20.0, 0.0, 20.0),
        Vec3::new(20.0, 0.0, 20.0),
        Vec3::new(20.0, 0.0, -20.0),
        Vec3::new(-20.0, 0.0, -20.0),
    );
    let scene =
        Scene::new(q.to_vec(), vec![0, 0], vec![diffuse(Vec3::splat(albedo), Vec3::ZERO)], vec!["floor".into()])
            .unwrap();
    compile(scene, BuildSettings::default())
}

fn top_camera() -> Camera {
    Camera { eye: DVec3::new(0.0, 6.0, 0.0), target: DVec3::ZERO, up: DVec3::NEG_Z, fov_deg: 60.0 }
}

/// The point on the floor seen through pixel (x, y)'s centre.
fn floor_point(c: &Compiled, s: &RenderSettings, x: u32, y: u32) -> DVec3 {
    let p = c.params(s, 0, 1).unwrap();
    let d = shared::camera::primary_direction(&p, x as f32 + 0.5, y as f32 + 0.5).as_dvec3();
    let eye = p.eye.truncate().as_dvec3();
    eye + d * (-eye.y / d.y)
}

/// Every pixel against `expected(point on the floor)`, within 1.5% (the pixel footprint's spread).
fn check_floor(c: &Compiled, s: &RenderSettings, r: &Rendered, expected: impl Fn(DVec3) -> f64, what: &str) {
    let m = r.mean();
    let mut worst = 0.0f64;
    for y in 0..s.height {
        for x in 0..s.width {
            let e = expected(floor_point(c, s, x, y));
            let v = m[(y * s.width + x) as usize][0] as f64;
            let err = (v - e).abs() / e.max(1e-3);
            if e > 1e-3 {
                worst = worst.max(err);
            } else {
                assert!(v.abs() < 2e-3, "{what}: pixel ({x}, {y}) {v}, expected {e}");
            }
        }
    }
    assert!(worst < 0.015, "{what}: worst relative error {worst}");
}

#[test]
fn point_light_over_a_diffuse_plane_gives_albedo_over_pi_times_i_cos_over_d2() {
    let (albedo, intensity, h) = (0.6, 10.0, 2.0);
    let mut c = floor(albedo as f32);
    c.scene.punctual_lights = vec![PunctualLight::point(DVec3::new(0.5, h, -0.3), Vec3::ONE, intensity as f32)];
    c.prepare_emitters();
    let s = settings(32, 16, 0, top_camera());
    let r = cpu::render(&c, &s, &no_progress).unwrap();
    check_floor(
        &c,
        &s,
        &r,
        |p| {
            let l = DVec3::new(0.5, h, -0.3) - p;
            let d2 = l.length_squared();
            albedo / PI * intensity * (h / d2.sqrt()) / d2
        },
        "point light",
    );
}

#[test]
fn directional_light_gives_albedo_over_pi_times_e_cos() {
    let (albedo, lux) = (0.8, 3.0);
    let dir = DVec3::new(0.3, -1.0, 0.2);
    let mut c = floor(albedo as f32);
    c.scene.punctual_lights = vec![PunctualLight::directional(dir, Vec3::ONE, lux as f32)];
    c.prepare_emitters();
    let s = settings(16, 4, 0, top_camera());
    let r = cpu::render(&c, &s, &no_progress).unwrap();
    let cos = -dir.normalize().y;
    check_floor(&c, &s, &r, |_| albedo / PI * lux * cos, "directional light");
}

#[test]
fn spot_light_follows_the_gltf_cone_falloff() {
    let (albedo, intensity, h) = (0.5, 20.0, 3.0);
    let (inner, outer) = (0.2f64, 0.45f64);
    let pos = DVec3::new(0.0, h, 0.0);
    let mut c = floor(albedo as f32);
    c.scene.punctual_lights =
        vec![PunctualLight::spot(pos, DVec3::NEG_Y, Vec3::ONE, intensity as f32, inner as f32, outer as f32)];
    c.prepare_emitters();
    let s = settings(48, 16, 0, top_camera());
    let r = cpu::render(&c, &s, &no_progress).unwrap();
    let expected = |p: DVec3| {
        let l = pos - p;
        let d2 = l.length_squared();
        let cos = h / d2.sqrt();
        // glTF: clamp((cos − cos outer) / (cos inner − cos outer), 0, 1)².
        let t = ((cos - outer.cos()) / (inner.cos() - outer.cos())).clamp(0.0, 1.0);
        albedo / PI * intensity * t * t * cos / d2
    };
    // Pixels across the cone's edges average a kink, and near the outer edge the steep square
    // bends within a pixel: check the smooth parts only.
    let m = r.mean();
    let (mut inside, mut edge, mut dark) = (0, 0, 0);
    for y in 0..s.height {
        for x in 0..s.width {
            let p = floor_point(&c, &s, x, y);
            let angle = (h / (pos - p).length()).acos();
            let v = m[(y * s.width + x) as usize][0] as f64;
            let e = expected(p);
            if angle < inner - 0.05 || (angle > inner + 0.05 && angle < outer - 0.12) {
                assert!((v - e).abs() < 0.03 * e + 1e-4, "pixel ({x}, {y}) at {angle} rad: {v} vs {e}");
                if angle < inner {
                    inside += 1
                } else {
                    edge += 1
                }
            } else if angle > outer + 0.03 {
                assert_eq!(v, 0.0, "outside the cone");
                dark += 1;
            }
        }
    }
    assert!(inside > 10 && edge > 10 && dark > 10, "{inside} {edge} {dark}");
}

#[test]
fn one_distribution_by_power_over_triangles_the_map_and_punctual_lights() {
    // A lamp of one triangle, a constant map and a point light.
    let mut c = floor(0.5);
    let lamp = procedural::quad(
        Vec3::new(-0.5, 2.0, -0.5),
        Vec3::new(0.5, 2.0, -0.5),
        Vec3::new(0.5, 2.0, 0.5),
        Vec3::new(-0.5, 2.0, 0.5),
    );
    let mut scene = c.scene.clone();
    scene.triangles.push(lamp[0]);
    let n = scene.triangles.len();
    let mut material_of: Vec<u32> = scene.info.iter().map(|i| i.material).collect();
    material_of.push(1);
    let mut materials = scene.materials.clone();
    materials.push(diffuse(Vec3::ZERO, Vec3::splat(4.0)));
    let scene = Scene::new(scene.triangles, material_of, materials, vec!["floor".into(), "lamp".into()]).unwrap();
    assert_eq!(scene.triangles.len(), n);
    c = compile(scene, BuildSettings::default());
    c.scene.environment_map = Some(EnvironmentMap::constant(8, 4, [0.5; 3]));
    c.scene.punctual_lights = vec![PunctualLight::point(DVec3::new(0.0, 1.0, 0.0), Vec3::ONE, 2.0)];
    c.prepare_emitters();
    assert_eq!(c.light_count, 3);
    let radius = 0.5 * (c.tree().bounds_max - c.tree().bounds_min).as_dvec3().length();
    let power = [0.5 * 4.0, 4.0 * PI * PI * radius * radius * 0.5, 4.0 * PI * 2.0];
    let total: f64 = power.iter().sum();
    let mut cdf = 0.0;
    for (l, p) in c.lights.iter().zip(power) {
        cdf += p / total;
        assert!((l.pmf as f64 - p / total).abs() < 1e-6, "{l:?}: pmf, expected {}", p / total);
        assert!((l.cdf as f64 - cdf).abs() < 1e-6);
    }
    assert!(c.lights[0].triangle < LIGHT_NOT_TRIANGLE && c.lights[1].triangle >= LIGHT_NOT_TRIANGLE);
    assert_eq!(c.lights[2].cdf, 1.0);
    // The lamp's own MIS weight reads its pmf from the same table: the image is finite and lit.
    let r = cpu::render(&c, &settings(16, 8, 2, top_camera()), &no_progress).unwrap();
    assert_eq!(r.zeroed_samples(), 0);
}

/// CPU and lavapipe agree bit for bit on punctual lights under an environment map.
#[test]
fn lavapipe_renders_punctual_lights_and_a_map_as_the_cpu_does() {
    let mut c = floor(0.7);
    c.scene.punctual_lights = vec![
        PunctualLight::point(DVec3::new(0.5, 2.0, -0.3), Vec3::new(1.0, 0.5, 0.2), 10.0),
        PunctualLight::spot(DVec3::new(-1.0, 3.0, 0.0), DVec3::new(0.2, -1.0, 0.0), Vec3::ONE, 30.0, 0.1, 0.4),
        PunctualLight::directional(DVec3::new(0.3, -1.0, 0.2), Vec3::splat(0.5), 2.0),
    ];
    c.scene.environment_map = Some(
        EnvironmentMap::new(
            8,
            4,
            (0..32).map(|i| [0.1 * (i % 8) as f32, 0.3, 0.02 * i as f32]).collect(),
            0.7,
            [0.0, 30.0, 10.0],
            "sky".into(),
        )
        .unwrap(),
    );
    c.prepare_emitters();
    let s = settings(16, 4, 2, top_camera());
    let a = cpu::render(&c, &s, &no_progress).unwrap();
    let g = gpu::Gpu::lavapipe().unwrap();
    let b = g.render(&c, &s, &no_progress).unwrap();
    assert_eq!(a.sum, b.sum);
    assert_eq!(a.sum_sq, b.sum_sq);
}

fn write(path: &std::path::Path, text: &str) {
    std::fs::write(path, text).unwrap();
}

/// A little-endian PFM of w × h texels, top row first in `texels`.
fn write_pfm(path: &std::path::Path, w: u32, h: u32, texel: impl Fn(u32, u32) -> [f32; 3]) {
    let mut bytes = format!("PF\n{w} {h}\n-1.0\n").into_bytes();
    for y in (0..h).rev() {
        for x in 0..w {
            for c in texel(x, y) {
                bytes.extend(c.to_le_bytes());
            }
        }
    }
    std::fs::write(path, bytes).unwrap();
}

fn scene_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("kdtrace-envlights-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let obj = paths::mesh("bunny-stanford-bun_zipper/bun_zipper.obj");
    std::fs::copy(obj, dir.join("bunny.obj")).unwrap();
    dir
}

#[test]
fn scene_files_give_maps_and_lights() {
    let dir = scene_dir("good");
    write_pfm(&dir.join("sky.pfm"), 8, 4, |x, y| [0.1 * x as f32, 0.2 * y as f32, 0.3]);
    let scene = dir.join("scene.toml");
    write(
        &scene,
        r#"
environment = { file = "sky.pfm", strength = 2.0, rotate = [0, 90, 0] }

[[mesh]]
file = "bunny.obj"

[[light]]
type = "point"
position = [0, 1, 0]
color = [1, 0.5, 0.25]
intensity = 5

[[light]]
type = "spot"
position = [0, 1, 0]
direction = [0, -1, 0]
intensity = 5
inner_cone_angle = 0.1
outer_cone_angle = 0.5

[[light]]
type = "directional"
direction = [0, -1, 0]
intensity = 2
"#,
    );
    let loaded = kdtrace::load(&scene, BuildSettings::default()).unwrap();
    let c = &loaded.compiled;
    let map = c.scene.environment_map.as_ref().expect("a map");
    assert_eq!((map.width, map.height, map.strength, map.rotate), (8, 4, 2.0, [0.0, 90.0, 0.0]));
    assert_eq!(map.texels[8 * 3 + 2], [0.2, 0.6, 0.3], "the top row is the first");
    assert_eq!(c.scene.punctual_lights.len(), 3);
    assert_eq!(c.light_count, 4);
    // A .kdc carries them: compiled, the scene renders the same bits.
    let kdc = dir.join("scene.kdc");
    kdtrace::render::kdc::write(&kdc, c, &BuildSettings::default(), &loaded.settings).unwrap();
    let back = kdtrace::load(&kdc, BuildSettings::default()).unwrap();
    assert_eq!(back.compiled.scene.environment_map.as_ref(), Some(map));
    assert_eq!(back.compiled.scene.punctual_lights, c.scene.punctual_lights);
    let s = settings(16, 4, 2, top_camera());
    let (a, b) = (cpu::render(c, &s, &no_progress).unwrap(), cpu::render(&back.compiled, &s, &no_progress).unwrap());
    assert!(a.sum.iter().any(|p| p.x > 0.0));
    assert!(a.sum == b.sum, "the compiled scene renders differently");
    // A crafted header's light is checked as a scene file's is.
    let mut bytes = std::fs::read(&kdc).unwrap();
    let at = bytes.windows(15).position(|w| w == b"\"intensity\":5.0").expect("the spot's intensity in the header");
    bytes[at..at + 15].copy_from_slice(b"\"intensity\":-50");
    kdtrace::render::kdc::seal(&mut bytes);
    std::fs::write(&kdc, &bytes).unwrap();
    let e = kdtrace::load(&kdc, BuildSettings::default()).err().expect("a negative intensity loaded");
    assert!(format!("{e:#}").contains("scene.kdc") && format!("{e:#}").contains("intensity"), "{e:#}");
}

#[test]
fn bad_maps_and_lights_are_errors_naming_the_file_and_line() {
    let dir = scene_dir("bad");
    write_pfm(&dir.join("nan.pfm"), 4, 2, |x, _| if x == 2 { [f32::NAN, 0.0, 0.0] } else { [1.0; 3] });
    write_pfm(&dir.join("negative.pfm"), 4, 2, |x, _| if x == 1 { [-1.0, 0.0, 0.0] } else { [1.0; 3] });
    std::fs::write(dir.join("broken.exr"), b"not an exr").unwrap();
    let cases: &[(&str, &[&str])] = &[
        ("environment = { file = \"missing.exr\" }", &["scene.toml:1:", "missing.exr"]),
        ("environment = { file = \"broken.exr\" }", &["scene.toml:1:", "broken.exr"]),
        ("environment = { file = \"nan.pfm\" }", &["scene.toml:1:", "nan.pfm", "(2, "]),
        ("environment = { file = \"negative.pfm\" }", &["negative.pfm", "non-negative"]),
        ("environment = { file = \"nan.pfm\", strenght = 1 }", &["scene.toml:1:", "strenght"]),
        ("environment = { file = \"nan.pfm\", strength = -1 }", &["scene.toml:1:", "strength"]),
        ("environment = \"sky.exr\"", &["scene.toml:1:", "colour [r, g, b] or a map"]),
        ("environment = [1, 2]", &["scene.toml:1:", "exactly 3"]),
        ("[[light]]\ntype = \"area\"", &["scene.toml:2:", "area"]),
        ("[[light]]\ntype = \"point\"\nintensity = -1", &["scene.toml:1:", "intensity"]),
        ("[[light]]\ntype = \"point\"\ndirection = [0, 1, 0]", &["scene.toml:1:", "no direction"]),
        ("[[light]]\ntype = \"directional\"\ndirection = [0, 0, 0]", &["scene.toml:1:", "direction"]),
        (
            "[[light]]\ntype = \"spot\"\ninner_cone_angle = 0.5\nouter_cone_angle = 0.2",
            &["scene.toml:1:", "cone angles"],
        ),
        ("[[light]]\ntype = \"point\"\nbrightness = 3", &["scene.toml:3:", "brightness"]),
    ];
    for (text, wanted) in cases {
        let scene = dir.join("scene.toml");
        write(&scene, &format!("{text}\n\n[[mesh]]\nfile = \"bunny.obj\"\n"));
        let err = match kdtrace::load(&scene, BuildSettings::default()) {
            Ok(_) => panic!("{text:?} loaded"),
            Err(e) => format!("{e:#}"),
        };
        for w in *wanted {
            assert!(err.contains(w), "{text:?}: error {err:?} lacks {w:?}");
        }
    }
}

#[test]
fn the_command_line_takes_a_map_or_a_colour() {
    let dir = scene_dir("cli");
    write_pfm(&dir.join("sky.pfm"), 8, 4, |x, _| [0.2 * x as f32, 0.5, 0.5]);
    let run = |env: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_kdtrace"))
            .args(["render", "bunny.obj", "--out", "out.exr", "--spp", "2", "--width", "8", "--height", "8", "--json"])
            .args(["--environment", env])
            .current_dir(&dir)
            .output()
            .unwrap()
    };
    let map = run("sky.pfm");
    assert!(map.status.success(), "{}", String::from_utf8_lossy(&map.stderr));
    assert!(String::from_utf8_lossy(&map.stdout).contains(r#""environment":"map""#));
    let colour = run("0.5,0.5,0.5");
    assert!(colour.status.success(), "{}", String::from_utf8_lossy(&colour.stderr));
    assert!(String::from_utf8_lossy(&colour.stdout).contains(r#""environment":"constant""#));
    for (bad, wanted) in [("missing.exr", "missing.exr"), ("1,x,2", "--environment 1,x,2")] {
        let out = run(bad);
        assert_eq!(out.status.code(), Some(2), "{bad}");
        assert!(
            String::from_utf8_lossy(&out.stderr).contains(wanted),
            "{bad}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

/// A Radiance `.hdr` map reads as the radiance it holds (within RGBE's 8-bit mantissas, which
/// share the brightest channel's exponent)
/// and renders; a broken one is an error naming the file.
#[test]
fn radiance_hdr_maps_read_and_render() {
    let dir = scene_dir("hdr");
    let (w, h) = (8u32, 4u32);
    let texel = |x: u32, y: u32| [0.1 + 0.3 * x as f32, 2.0 + y as f32, 0.05];
    let pixels: Vec<image::Rgb<f32>> = (0..w * h).map(|i| image::Rgb(texel(i % w, i / w))).collect();
    let mut bytes = Vec::new();
    image::codecs::hdr::HdrEncoder::new(&mut bytes).encode(&pixels, w as usize, h as usize).unwrap();
    std::fs::write(dir.join("sky.hdr"), &bytes).unwrap();
    let map = kdtrace::scene::EnvironmentMap::read(&dir.join("sky.hdr"), 1.0, [0.0; 3]).unwrap();
    assert_eq!((map.width, map.height), (w, h));
    for (i, t) in map.texels.iter().enumerate() {
        let want = texel(i as u32 % w, i as u32 / w);
        // The mantissas share the brightest channel's exponent.
        let step = want.iter().fold(0f32, |a, &b| a.max(b)) / 128.0;
        for k in 0..3 {
            assert!((t[k] - want[k]).abs() <= step, "texel {i}: {t:?}, want {want:?}");
        }
    }
    write(&dir.join("scene.toml"), "environment = { file = \"sky.hdr\" }\n\n[[mesh]]\nfile = \"bunny.obj\"\n");
    let l = kdtrace::load(&dir.join("scene.toml"), BuildSettings::default()).unwrap();
    assert!(l.compiled.scene.environment_map.is_some());
    std::fs::write(dir.join("broken.hdr"), &bytes[..bytes.len() / 2]).unwrap();
    let e = kdtrace::scene::EnvironmentMap::read(&dir.join("broken.hdr"), 1.0, [0.0; 3]).unwrap_err();
    assert!(format!("{e:#}").contains("broken.hdr"), "{e:#}");
}
