//! Textures, texture coordinates, vertex normals and alpha cut-outs, end to end: scenes written
//! here (OBJ, MTL, PNG and JPEG made by the test), loaded, rendered on the CPU and on lavapipe
//! (bit for bit the same, specialised and generic), and their error messages.
#[path = "common/run.rs"]
mod run;
use kdtrace::kdbuild::BuildSettings;
use kdtrace::render::{cpu, gpu, kdc, Compiled, Rendered};
use kdtrace::scene::texture::srgb_to_linear;
use kdtrace::settings::camera::Camera;
use kdtrace::settings::{Aov, RenderSettings, Traversal};
use shared::glam::{DVec3, Vec3, Vec4};
use shared::layout::{
    RayQuery, RayResult, NO_TEXTURE, RAY_ALPHA_MASKS, RAY_ANY_HIT, RAY_SHORT_STACK, TEXTURE_ALBEDO, TEXTURE_ALPHA,
    TEXTURE_EMISSION, TEXTURE_METALLIC, TEXTURE_ROUGHNESS,
};
use std::path::{Path, PathBuf};

#[path = "common/kdc_craft.rs"]
mod craft;

fn none(_: u64, _: u64) {}

/// A fresh folder for one test's files.
fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("kdtrace-textures-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// An RGBA image of `w`×`h` texels, `f(x, y)` with row 0 at the top, as PNG or JPEG.
fn image(dir: &Path, name: &str, w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 4]) -> PathBuf {
    let p = dir.join(name);
    let img = image::RgbaImage::from_fn(w, h, |x, y| image::Rgba(f(x, y)));
    if name.ends_with(".jpg") {
        image::DynamicImage::ImageRgba8(img).to_rgb8().save(&p).unwrap();
    } else {
        img.save(&p).unwrap();
    }
    p
}

fn load(path: &Path) -> Compiled {
    kdtrace::load(path, BuildSettings::default()).unwrap().compiled
}

fn settings(eye: [f64; 3], fov: f32, side: u32, spp: u32, bounces: u32) -> RenderSettings {
    let camera = Camera { eye: DVec3::from(eye), target: DVec3::ZERO, up: DVec3::Y, fov_deg: fov };
    RenderSettings {
        width: side,
        height: side,
        spp,
        max_bounces: bounces,
        seed: 3,
        ..RenderSettings::with_camera(camera)
    }
}

fn bits(r: &Rendered) -> (Vec<u32>, Vec<u32>) {
    let b = |v: &[Vec4]| v.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect();
    (b(&r.sum), b(&r.sum_sq))
}

/// Renders on the CPU (specialised and generic) and on lavapipe (both) and checks that all four
/// give the same bits; returns the CPU's image.
fn render_everywhere(c: &Compiled, s: &RenderSettings, g: &gpu::Gpu) -> Rendered {
    let generic = RenderSettings { specialize: false, ..*s };
    let a = cpu::render(c, s, &none).unwrap();
    let b = cpu::render(c, &generic, &none).unwrap();
    assert!(bits(&a) == bits(&b), "the CPU's specialised variant differs from its generic code");
    let ga = g.render(c, s, &none).unwrap();
    assert!(bits(&a) == bits(&ga) && a.primary == ga.primary, "lavapipe's specialised image differs from the CPU's");
    let gb = g.render(c, &generic, &none).unwrap();
    assert!(bits(&a) == bits(&gb), "lavapipe's generic image differs from the CPU's");
    a
}

/// Quadrant colours of the test texture, top left, top right, bottom left, bottom right (sRGB).
const QUADRANTS: [[u8; 4]; 4] = [[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255], [128, 128, 128, 255]];

/// A unit quad at z = 0 from (−1, −1) to (1, 1), uv (0, 0) to (1, 1), textured with `texture`.
fn textured_quad(dir: &Path, texture: &str) -> PathBuf {
    let tex = if texture.ends_with(".jpg") { 64 } else { 16 };
    image(dir, texture, tex, tex, |x, y| QUADRANTS[(2 * (y >= tex / 2) as usize) + (x >= tex / 2) as usize]);
    write(dir, "quad.mtl", &format!("newmtl tex\nKd 0.5 0.5 0.5\nmap_Kd {texture}\n"));
    write(
        dir,
        "quad.obj",
        "mtllib quad.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n\
         usemtl tex\nf 1/1/1 2/2/1 3/3/1 4/4/1\n",
    )
}

fn linear(c: [u8; 4]) -> [f32; 3] {
    [0, 1, 2].map(|i| srgb_to_linear(c[i] as f64 / 255.0) as f32)
}

/// Each quadrant of the image of a textured quad shows its texel colour (albedo and, under a
/// white sky that a plane reflects exactly once, radiance); the CPU and lavapipe agree bit for
/// bit. A JPEG texture gives the same colours within its compression error.
#[test]
fn a_textured_quad_shows_its_quadrants_on_both_devices() {
    let g = gpu::Gpu::lavapipe().unwrap();
    for (texture, tolerance) in [("quadrants.png", 2e-3), ("quadrants.jpg", 0.03)] {
        let dir = folder(&format!("quad-{texture}"));
        let c = load(&textured_quad(&dir, texture));
        assert_eq!(c.scene.texture_sources.len(), 1);
        // tan(15°) · 3 = 0.8: the quad fills the view.
        let s = RenderSettings { environment: Vec3::ONE, ..settings([0.0, 0.0, 3.0], 30.0, 16, 4, 2) };
        for aov in [Aov::Albedo, Aov::Radiance] {
            let r = if texture.ends_with(".png") {
                render_everywhere(&c, &RenderSettings { aov, ..s }, &g)
            } else {
                cpu::render(&c, &RenderSettings { aov, ..s }, &none).unwrap()
            };
            let mean = r.mean();
            for (q, colour) in QUADRANTS.iter().enumerate() {
                let want = linear(*colour);
                // Pixels well inside the quadrant (the texture blends across its middle).
                let (x0, y0) = (if q % 2 == 0 { 1 } else { 10 }, if q < 2 { 1 } else { 10 });
                for y in y0..y0 + 5 {
                    for x in x0..x0 + 5 {
                        let got = mean[y * 16 + x];
                        for k in 0..3 {
                            assert!(
                                (got[k] - want[k]).abs() <= tolerance,
                                "{texture} {aov:?}: pixel ({x}, {y}) is {got:?}, quadrant {q} is {want:?}"
                            );
                        }
                    }
                }
            }
        }
    }
}

/// The alpha scene: a red wall at z = −1, a white quad at z = 0 cut out where `mask` is 0 (a
/// 16×16 greyscale image, column x's value `mask(x)`), a small lamp at z = 2 shining down −z.
/// `quad = false` leaves the quad out.
fn alpha_scene(dir: &Path, mask: impl Fn(u32) -> u8, quad: bool) -> PathBuf {
    image(dir, "mask.png", 16, 16, |x, _| {
        let m = mask(x);
        [m, m, m, 255]
    });
    write(
        dir,
        "alpha.mtl",
        "newmtl wall\nKd 0.8 0.1 0.1\nnewmtl leaf\nKd 0.9 0.9 0.9\nmap_d mask.png\nnewmtl lamp\nKd 0 0 0\nKe 40 40 40\n",
    );
    let leaf = if quad { "usemtl leaf\nf 5/1 6/2 7/3 8/4\n" } else { "" };
    write(
        dir,
        "alpha.obj",
        &format!(
            "mtllib alpha.mtl\nv -3 -3 -1\nv 3 -3 -1\nv 3 3 -1\nv -3 3 -1\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n\
             v -0.25 -0.25 2\nv -0.25 0.25 2\nv 0.25 0.25 2\nv 0.25 -0.25 2\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
             usemtl wall\nf 1 2 3 4\n{leaf}usemtl lamp\nf 9 10 11 12\n"
        ),
    )
}

fn near(a: [f32; 3], b: [f32; 3]) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() < 1e-6)
}

/// The pixel columns whose every camera ray crosses the plane z = `z` at x within `lo..hi`
/// (camera at z = 6 looking down −z, 40° field of view, `side` pixels).
fn columns(side: u32, z: f64, lo: f64, hi: f64) -> Vec<usize> {
    let t = (20f64).to_radians().tan() * (6.0 - z);
    (0..side as usize)
        .filter(|&x| {
            let a = (x as f64 / side as f64 * 2.0 - 1.0) * t;
            let b = ((x + 1) as f64 / side as f64 * 2.0 - 1.0) * t;
            a > lo && b < hi
        })
        .collect()
}

/// A quad whose mask is 0 where the wall shows through: camera rays see the wall, shadow rays
/// reach the lamp, bounce rays pass, in both traversals and on both devices; where the mask is 1
/// it is an ordinary surface.
#[test]
fn alpha_cut_outs_let_every_ray_through() {
    let s = settings([0.0, 0.0, 6.0], 40.0, 48, 4, 3);
    let no_quad = load(&alpha_scene(&folder("alpha-none"), |_| 255, false));
    let cut = load(&alpha_scene(&folder("alpha-cut"), |_| 0, true));
    let half = load(&alpha_scene(&folder("alpha-half"), |x| if x < 8 { 0 } else { 255 }, true));
    let opaque = load(&alpha_scene(&folder("alpha-opaque"), |_| 255, true));
    // A quad cut out everywhere is no quad at all, for every ray of every bounce: the same bits.
    for traversal in [Traversal::Full, Traversal::Short] {
        let s = RenderSettings { traversal, ..s };
        let reference = cpu::render(&no_quad, &s, &none).unwrap();
        let other = cpu::render(&cut, &s, &none).unwrap();
        assert!(bits(&other) == bits(&reference), "{traversal:?}");
        assert!(bits(&cpu::render(&opaque, &s, &none).unwrap()) != bits(&reference), "{traversal:?}");
    }
    let g = gpu::Gpu::lavapipe().unwrap();
    for traversal in [Traversal::Full, Traversal::Short] {
        let s = RenderSettings { traversal, ..s };
        let a = render_everywhere(&cut, &s, &g);
        assert!(bits(&a) == bits(&cpu::render(&no_quad, &s, &none).unwrap()));
        render_everywhere(&half, &s, &g);
    }
    // Ray batches: with RAY_ALPHA_MASKS a ray through the cut-out half reaches the wall, on the
    // CPU and on lavapipe alike; without, it stops at the quad.
    let params = half.bounds_params();
    let view = half.view(&params);
    let ray = |x: f32, flags: u32| RayQuery {
        origin: Vec4::new(x, 0.3, 3.0, 0.0),
        dir: Vec4::new(0.0, 0.0, -1.0, 0.0),
        t_max: f32::MAX,
        flags,
        _pad: [0; 2],
    };
    let rays: Vec<RayQuery> = [0, RAY_SHORT_STACK, RAY_ANY_HIT]
        .iter()
        .flat_map(|&f| [ray(-0.5, f), ray(-0.5, f | RAY_ALPHA_MASKS), ray(0.5, f | RAY_ALPHA_MASKS)])
        .collect();
    let on_cpu: Vec<RayResult> = rays.iter().map(|q| shared::raycast::cast_ray(&view, q)).collect();
    assert_eq!(on_cpu, g.cast(&half, &rays).unwrap());
    for (k, r) in on_cpu.chunks(3).enumerate() {
        // The quad at z = 0 (t = 3), the wall behind the cut-out (t = 4), the quad's opaque half
        // (an any-hit query, the last group, may stop at any hit that counts).
        assert_eq!(r[1].t, 4.0, "{r:?}");
        if k < 2 {
            assert_eq!([r[0].t, r[2].t], [3.0, 3.0], "{r:?}");
        }
    }
    // Half cut out (u < 1/2): the camera sees the wall through the left half, the quad on the
    // right. Rows near the middle only (the lamp hides the centre).
    let side = 48;
    let albedo = cpu::render(&half, &RenderSettings { aov: Aov::Albedo, ..s }, &none).unwrap().mean();
    let rows = [14usize, 15, 32, 33];
    for &x in &columns(side, 0.0, -0.9, -0.1) {
        for &y in &rows {
            assert!(
                near(albedo[y * 48 + x], [0.8, 0.1, 0.1]),
                "pixel ({x}, {y}) should see the wall through the cut-out"
            );
        }
    }
    for &x in &columns(side, 0.0, 0.1, 0.9) {
        for &y in &rows {
            assert!(near(albedo[y * 48 + x], [0.9, 0.9, 0.9]), "pixel ({x}, {y}) should see the quad");
        }
    }
    // Direct light only: the wall beside the quad's left edge (its lamp rays cross the left
    // half) is lit as if there were no quad; an opaque quad shadows it.
    // (Wall points with x in −1.37..−1.17: the camera sees them past the quad's edge, and every
    // ray to the lamp, x in −0.25..0.25 at z = 2, crosses z = 0 within the quad's left half.)
    let side = 96;
    let direct = RenderSettings { max_bounces: 0, width: side, height: side, ..s };
    let [without, with_half, with_opaque] =
        [&no_quad, &half, &opaque].map(|c| cpu::render(c, &direct, &none).unwrap().mean());
    let beside = columns(side, -1.0, -1.37, -1.17);
    assert!(beside.len() >= 2, "{beside:?}");
    for &x in &beside {
        for y in 42..54 {
            let i = y * side as usize + x;
            assert!(without[i][0] > 0.0, "pixel ({x}, {y}) unlit without the quad");
            assert_eq!(with_half[i], without[i], "pixel ({x}, {y}): the cut-out casts a shadow");
            assert_eq!(with_opaque[i], [0.0; 3], "pixel ({x}, {y}): the opaque quad casts no shadow");
        }
    }
}

/// A UV sphere of `stacks` × `slices` (radius 1, at the origin), with vertex normals or without.
fn sphere(dir: &Path, normals: bool) -> PathBuf {
    let (stacks, slices) = (6, 8);
    let mut obj = String::from("mtllib sphere.mtl\nusemtl grey\n");
    for i in 0..=stacks {
        let theta = std::f64::consts::PI * i as f64 / stacks as f64;
        for j in 0..slices {
            let phi = 2.0 * std::f64::consts::PI * j as f64 / slices as f64;
            let p = [theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()];
            obj += &format!("v {} {} {}\nvn {} {} {}\n", p[0], p[1], p[2], p[0], p[1], p[2]);
        }
    }
    let id = |i: usize, j: usize| i * slices + j % slices + 1;
    for i in 0..stacks {
        for j in 0..slices {
            let q = [id(i, j), id(i, j + 1), id(i + 1, j + 1), id(i + 1, j)];
            let corner = |k: usize| if normals { format!("{}//{}", q[k], q[k]) } else { q[k].to_string() };
            obj +=
                &format!("f {} {} {}\nf {} {} {}\n", corner(0), corner(1), corner(2), corner(0), corner(2), corner(3));
        }
    }
    write(dir, "sphere.mtl", "newmtl grey\nKd 0.8 0.8 0.8\n");
    write(dir, "sphere.obj", &obj)
}

/// The largest difference between horizontally adjacent normals that both face the camera.
fn largest_step(normals: &[[f32; 3]], side: usize) -> f32 {
    let mut most = 0f32;
    for y in 0..side {
        for x in 0..side - 1 {
            let (a, b) = (normals[y * side + x], normals[y * side + x + 1]);
            if a[2] > 0.7 && b[2] > 0.7 {
                let d = Vec3::from(a) - Vec3::from(b);
                most = most.max(d.length());
            }
        }
    }
    most
}

/// Vertex normals shade a low-poly sphere smoothly: the normal image has no steps at the
/// triangle edges (the flat one does), a hit's shading normal is the interpolation of its
/// vertex normals, and under a white sky no pixel reflects more than arrives.
#[test]
fn vertex_normals_shade_smoothly_and_keep_energy() {
    let smooth = load(&sphere(&folder("sphere-smooth"), true));
    let flat = load(&sphere(&folder("sphere-flat"), false));
    assert!(!smooth.scene.attributes.is_empty() && flat.scene.attributes.is_empty());
    let s = RenderSettings { aov: Aov::Normal, ..settings([0.0, 0.3, 4.0], 40.0, 64, 1, 0) };
    let [smooth_n, flat_n] = [&smooth, &flat].map(|c| cpu::render(c, &s, &none).unwrap().mean());
    let (smooth_step, flat_step) = (largest_step(&smooth_n, 64), largest_step(&flat_n, 64));
    assert!(smooth_step < 0.25, "vertex normals: steps of {smooth_step} between neighbours");
    assert!(flat_step > 0.4, "flat shading: steps of only {flat_step} between neighbours");
    // One ray, checked against the interpolation written out in f64.
    let params = smooth.params(&s, 0, 1).unwrap();
    let view = smooth.view(&params);
    let eye = Vec3::new(0.0, 0.3, 4.0);
    let dir = Vec3::new(0.21, -0.13, -1.0);
    let hit = shared::raycast::closest(&view, 0, eye, dir, f32::MAX).hit;
    assert!(hit.is_hit());
    let b = shared::surface::hit_weights(&hit);
    let a = &smooth.scene.attributes[hit.triangle as usize];
    let want = ([a.n0, a.n1, a.n2].iter().zip([b.0, b.1, b.2]))
        .fold(DVec3::ZERO, |acc, (n, w)| acc + n.truncate().as_dvec3() * w as f64)
        .normalize();
    let tri = &smooth.scene.triangles[hit.triangle as usize];
    let (flat_n, wo) = (shared::triangle::stored_normal(tri), -dir.normalize());
    let flat_n = if flat_n.dot(wo) < 0.0 { -flat_n } else { flat_n };
    let v = shared::features::Variant::GENERIC_SPEC;
    let got = shared::surface::shading_normal(&view, v, hit.triangle, b, flat_n, wo);
    assert!((got.as_dvec3() - want).length() < 1e-6, "shading normal {got} vs interpolation {want}");
    assert!((got - flat_n).length() > 1e-3, "the shading normal is the flat one");
    // Furnace: albedo 0.8 under a white sky, many bounces; no sample exceeds 1.
    let furnace = RenderSettings { environment: Vec3::ONE, ..settings([0.0, 0.3, 4.0], 40.0, 24, 16, 8) };
    let r = cpu::render(&smooth, &furnace, &none).unwrap();
    let most = r.mean().iter().flat_map(|p| *p).fold(0f32, f32::max);
    assert!(most <= 1.0 + 1e-5, "a pixel reflects {most} of a white sky");
    assert!(r.mean().iter().filter(|p| p[0] > 0.5 && p[0] < 1.0).count() > 100);
    // The normal image and the lit sphere agree on both devices; at 5 spp the CPU's specialised
    // variant is the lane integrator (`shared::lanes`), which shades by the vertex normals too.
    let g = gpu::Gpu::lavapipe().unwrap();
    render_everywhere(&smooth, &RenderSettings { width: 16, height: 16, ..s }, &g);
    render_everywhere(&smooth, &RenderSettings { width: 16, height: 16, spp: 5, ..furnace }, &g);
}

/// The MTL keys map as the README says: map_Kd, map_d, map_Ke, map_Pr and map_Pm fill their slots
/// (map_Ke also sets the emission to the texture's mean; map_Pr and map_Pm make the material
/// principled); a constant dissolve below 0.5 (d, or
/// 1 − Tr) cuts faces out, except glass; a material without keys stays diffuse.
#[test]
fn mtl_keys_map_to_textures_and_cut_outs() {
    let dir = folder("mtl");
    for name in ["a.png", "m.png", "r.png", "p.png"] {
        image(&dir, name, 2, 2, |x, _| [200 * x as u8, 50, 25, 255]);
    }
    image(&dir, "e.jpg", 8, 8, |_, _| [255, 255, 255, 255]);
    let mtl = "newmtl painted\nKd 0.5 0.5 0.5\nmap_Kd a.png\nmap_d m.png\nmap_Ke e.jpg\nmap_Pr r.png\nmap_Pm p.png\n\
               newmtl faded\nKd 1 1 1\nd 0.3\nnewmtl tr\nKd 1 1 1\nTr 0.8\nnewmtl solid\nKd 1 1 1\nTr 0.2\n\
               newmtl glass\nillum 7\nNi 1.5\nd 0.2\nnewmtl plain\nKd 0.25 0.5 0.75\n";
    write(&dir, "keys.mtl", mtl);
    let mut obj = String::from("mtllib keys.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n");
    for m in ["painted", "faded", "tr", "solid", "glass", "plain"] {
        obj += &format!("usemtl {m}\nf 1/1 2/2 3/3\n");
    }
    let path = write(&dir, "keys.obj", &obj);
    let mesh = kdtrace::scene::obj::load_mesh(&path, &kdtrace::files::Disk).unwrap();
    let w = &mesh.scene;
    let m = |name: &str| w.materials[w.material_names.iter().position(|n| n == name).unwrap()];
    let painted = m("painted");
    for slot in [TEXTURE_ALBEDO, TEXTURE_ALPHA, TEXTURE_EMISSION, TEXTURE_ROUGHNESS, TEXTURE_METALLIC] {
        assert_ne!(painted.textures[slot], NO_TEXTURE, "slot {slot}");
    }
    assert_eq!(w.textures.textures.len(), 5);
    // Roughness and metallic maps make the material principled, whose lobes read them.
    assert_eq!(painted.kind, shared::layout::MATERIAL_PRINCIPLED);
    // A white emission texture: the constant emission is its mean, 1.
    assert_eq!(painted.emission.truncate(), Vec3::ONE);
    let plain = m("plain");
    assert_eq!((plain.kind, plain.textures), (shared::layout::MATERIAL_DIFFUSE, [NO_TEXTURE; 8]));
    assert_eq!(plain.albedo.truncate(), Vec3::new(0.25, 0.5, 0.75));
    // faded (d 0.3) and tr (Tr 0.8) are cut out; solid (Tr 0.2), glass and the rest stay.
    assert_eq!(w.triangles.len(), 4);
    assert!(mesh.warnings.iter().any(|m| m.contains("2 faces cut out")), "{:?}", mesh.warnings);
    assert_eq!(m("glass").kind, shared::layout::MATERIAL_DIELECTRIC);
    // Missing and undecodable images: errors naming the image and the MTL line.
    for (file, line, what) in [("missing.png", 3, "cannot read"), ("broken.png", 3, "not a PNG or JPEG")] {
        std::fs::write(dir.join("broken.png"), b"\x89PNG but not really").unwrap();
        write(&dir, "bad.mtl", &format!("newmtl x\nKd 1 1 1\nmap_Kd {file}\n"));
        let path = write(&dir, "bad.obj", "mtllib bad.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\n");
        let e = format!("{:#}", kdtrace::load(&path, BuildSettings::default()).err().unwrap());
        assert!(e.contains(file) && e.contains(&format!("bad.mtl:{line}")) && e.contains(what), "{e}");
    }
}

/// A scene file's diffuse `albedo_texture` (relative to the file) textures the mesh; a missing
/// one is an error at its line and column; it applies to diffuse materials only.
#[test]
fn scene_files_take_an_albedo_texture() {
    let dir = folder("toml");
    textured_quad(&dir, "quadrants.png");
    std::fs::create_dir_all(dir.join("textures")).unwrap();
    image(&dir.join("textures"), "blue.png", 4, 4, |_, _| [0, 0, 255, 255]);
    let scene = |material: &str| {
        write(
            &dir,
            "scene.toml",
            &format!(
                "[camera]\neye = [0, 0, 3]\ntarget = [0, 0, 0]\nfov = 30\nwidth = 8\nheight = 8\n\n[materials.blue]\n\
                 {material}\n\n[[mesh]]\nfile = \"quad.obj\"\nmaterial = \"blue\"\n"
            ),
        )
    };
    let path = scene("albedo_texture = \"textures/blue.png\"");
    let loaded = kdtrace::load(&path, BuildSettings::default()).unwrap();
    let c = &loaded.compiled;
    let blue = c.scene.materials[c.scene.info[0].material as usize];
    assert_ne!(blue.textures[TEXTURE_ALBEDO], NO_TEXTURE);
    let (lo, hi) = c.world_bounds();
    let s = RenderSettings { aov: Aov::Albedo, ..loaded.settings.resolve(lo, hi).unwrap() };
    for p in cpu::render(c, &s, &none).unwrap().mean() {
        assert!((p[2] - 1.0).abs() < 1e-3 && p[0].abs() < 1e-3, "{p:?}");
    }
    // `export` moves the texture's path with the file.
    let out = dir.join("elsewhere");
    std::fs::create_dir_all(&out).unwrap();
    let exported = out.join("exported.toml");
    run::export(&path, &exported);
    let text = std::fs::read_to_string(&exported).unwrap();
    assert!(text.contains("albedo_texture = \"../textures/blue.png\""), "{text}");
    let again = load(&exported);
    assert_eq!(again.scene.textures, c.scene.textures);
    let path = scene("albedo_texture = \"textures/nothere.png\"");
    let e = format!("{:#}", kdtrace::load(&path, BuildSettings::default()).err().unwrap());
    assert!(e.contains("nothere.png") && e.contains("scene.toml:9:18"), "{e}");
    let path = scene("type = \"conductor\"\nmetal = \"Au\"\nalbedo_texture = \"textures/blue.png\"");
    let e = format!("{:#}", kdtrace::load(&path, BuildSettings::default()).err().unwrap());
    assert!(e.contains("scene.toml:") && e.contains("albedo_texture does not apply to a conductor material"), "{e}");
    // A principled material's `base_color_texture` fills the same slot: the albedo image is blue.
    let path = scene("type = \"principled\"\nbase_color_texture = \"textures/blue.png\"");
    let loaded = kdtrace::load(&path, BuildSettings::default()).unwrap();
    let c = &loaded.compiled;
    let paint = c.scene.materials[c.scene.info[0].material as usize];
    assert_eq!(paint.kind, shared::layout::MATERIAL_PRINCIPLED);
    assert_ne!(paint.textures[TEXTURE_ALBEDO], NO_TEXTURE);
    let s = RenderSettings { aov: Aov::Albedo, ..loaded.settings.resolve(lo, hi).unwrap() };
    for p in cpu::render(c, &s, &none).unwrap().mean() {
        assert!((p[2] - 1.0).abs() < 1e-3 && p[0].abs() < 1e-3, "{p:?}");
    }
}

/// A `.kdc` keeps textures, texture coordinates, vertex normals and masks: the compiled scene
/// renders the source scene's image bit for bit.
#[test]
fn compiled_scenes_keep_textures_and_attributes() {
    let quad = folder("kdc-quad");
    let alpha = folder("kdc-alpha");
    let ball = folder("kdc-sphere");
    let cases = [
        (textured_quad(&quad, "quadrants.png"), settings([0.0, 0.0, 3.0], 30.0, 12, 2, 2)),
        (alpha_scene(&alpha, |x| if x < 8 { 0 } else { 255 }, true), settings([0.0, 0.0, 6.0], 40.0, 12, 2, 2)),
        (sphere(&ball, true), settings([0.0, 0.3, 4.0], 40.0, 12, 2, 2)),
    ];
    for (path, s) in cases {
        let source = load(&path);
        let kdc_path = path.with_extension("kdc");
        kdc::write(&kdc_path, &source, &BuildSettings::default(), &Default::default()).unwrap();
        let back = kdc::read(&kdc_path).unwrap().compiled;
        assert_eq!(back.scene.textures, source.scene.textures);
        assert_eq!(back.scene.attributes, source.scene.attributes);
        assert_eq!(back.scene.texture_sources, source.scene.texture_sources);
        let s = RenderSettings { environment: Vec3::splat(0.5), ..s };
        for aov in [Aov::Radiance, Aov::Albedo, Aov::Normal] {
            let s = RenderSettings { aov, ..s };
            let (a, b) = (cpu::render(&source, &s, &none).unwrap(), cpu::render(&back, &s, &none).unwrap());
            assert!(bits(&a) == bits(&b), "{}: {aov:?}", path.display());
        }
    }
}

/// A crafted `.kdc` whose material names a texture beyond the table, whose table points past the
/// texels, or whose vertex attributes are not finite is refused, naming the problem.
#[test]
fn compiled_scenes_with_bad_textures_or_attributes_are_refused() {
    let dir = folder("kdc-crafted");
    let source = load(&textured_quad(&dir, "quadrants.png"));
    let path = dir.join("quad.kdc");
    kdc::write(&path, &source, &BuildSettings::default(), &Default::default()).unwrap();
    let good = std::fs::read(&path).unwrap();
    // The texture slots sit after kind, padding and six Vec4s.
    let slots = 16 + 6 * 16;
    type Edit = Box<dyn Fn(&mut craft::Parts)>;
    let edits: [(&str, Edit); 4] = [
        ("texture 99 out of range", Box::new(move |p| craft::put_u32(p, craft::section_offset(p, 2) + slots, 99))),
        ("outside the buffer", Box::new(|p| craft::put_u32(p, craft::section_offset(p, 7), 1 << 20))),
        ("not a valid texture", Box::new(|p| craft::put_u32(p, craft::section_offset(p, 7) + 4, 0))),
        ("vertex attributes not finite", Box::new(|p| craft::put_f32(p, craft::section_offset(p, 6) + 4, f32::NAN))),
    ];
    for (want, edit) in edits {
        let mut parts = craft::split(&good);
        edit(&mut parts);
        let e = format!("{:#}", kdc::decode(&path, &craft::join(&parts)).err().expect(want));
        assert!(e.contains(want) && e.contains("quad.kdc"), "{want}: {e}");
    }
    assert!(kdc::decode(&path, &craft::join(&craft::split(&good))).is_ok());
}
