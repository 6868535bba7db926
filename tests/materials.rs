//! The BSDFs' own properties, apart from their sampling (χ² in `chi2.rs`): the exact conductor
//! Fresnel term at the angles where it has a closed form, the GGX distribution's normalisation,
//! reciprocity, energy (a furnace per material: what sampling returns on average against the
//! quadrature of f·cos, never above 1), the smooth mirror, and a render of a mirror furnace
//! whose every pixel has a known value.
#[path = "common/run.rs"]
mod run;
use kdtrace::{
    compile,
    kdbuild::BuildSettings,
    render::cpu,
    scene::{conductor, procedural::box_triangles, Scene},
    settings::{camera::Camera, RenderSettings},
};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use shared::{
    features::Variant,
    glam::{DVec3, Vec3},
    material::{eval, fresnel_conductor, ggx_d, is_delta, sample, DELTA_PDF},
};
use std::f64::consts::PI;

const V: Variant = Variant::GENERIC_SPEC;

fn gold(alpha: f32) -> shared::layout::Material {
    conductor(Vec3::new(0.143, 0.375, 1.442), Vec3::new(3.983, 2.386, 1.603), alpha, Vec3::ZERO)
}

/// A conductor whose Fresnel term is 1 at every angle (η = 0): all loss is the microfacets'.
fn white(alpha: f32) -> shared::layout::Material {
    conductor(Vec3::ZERO, Vec3::ONE, alpha, Vec3::ZERO)
}

#[test]
fn conductor_fresnel_has_its_closed_forms() {
    let (eta, k) = (Vec3::new(0.2, 1.1, 2.5), Vec3::new(3.9, 2.4, 0.3));
    // Normal incidence: ((η − 1)² + κ²) / ((η + 1)² + κ²).
    let f0 = fresnel_conductor(1.0, eta, k);
    for c in 0..3 {
        let (e, kk) = (eta[c] as f64, k[c] as f64);
        let want = ((e - 1.0).powi(2) + kk * kk) / ((e + 1.0).powi(2) + kk * kk);
        assert!((f0[c] as f64 - want).abs() < 1e-5, "channel {c}: {} against {want}", f0[c]);
    }
    // Grazing: everything is reflected.
    assert!((fresnel_conductor(0.0, eta, k) - Vec3::ONE).abs().max_element() < 1e-5);
    // κ = 0 is a dielectric: η = 1.5 reflects 4% at normal incidence, and at 60° the average of
    // the s and p reflectances of Fresnel's equations.
    let glass = fresnel_conductor(1.0, Vec3::splat(1.5), Vec3::ZERO);
    assert!((glass.x - 0.04).abs() < 1e-6);
    let (ci, sin_t) = (0.5f64, (0.75f64).sqrt() / 1.5);
    let ct = (1.0 - sin_t * sin_t).sqrt();
    let rs = ((ci - 1.5 * ct) / (ci + 1.5 * ct)).powi(2);
    let rp = ((1.5 * ci - ct) / (1.5 * ci + ct)).powi(2);
    let at60 = fresnel_conductor(0.5, Vec3::splat(1.5), Vec3::ZERO).x as f64;
    assert!((at60 - 0.5 * (rs + rp)).abs() < 1e-5, "{at60} against {}", 0.5 * (rs + rp));
}

/// ∫ D(m) cos θ_m dω = 1: the microfacets' projected area is the surface's.
#[test]
fn ggx_distribution_is_normalised() {
    for alpha in [0.05f32, 0.2, 0.5, 1.0] {
        // Midpoint rule in θ, fine enough near the peak (θ ≲ 4α).
        let steps = 400_000;
        let mut sum = 0f64;
        for i in 0..steps {
            let theta = (i as f64 + 0.5) / steps as f64 * PI / 2.0;
            let m = Vec3::new(theta.sin() as f32, 0.0, theta.cos() as f32);
            sum += ggx_d(alpha, m) as f64 * theta.cos() * theta.sin() * 2.0 * PI * (PI / 2.0 / steps as f64);
        }
        assert!((sum - 1.0).abs() < 2e-3, "α {alpha}: ∫ D cos = {sum}");
    }
}

fn direction(theta_deg: f32, phi_deg: f32) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

#[test]
fn rough_conductor_is_reciprocal() {
    let m = gold(0.3);
    let mut rng = Pcg64::seed_from_u64(7);
    for _ in 0..10_000 {
        let a = direction(rng.random_range(0.0..89.0), rng.random_range(0.0..360.0));
        let b = direction(rng.random_range(0.0..89.0), rng.random_range(0.0..360.0));
        let (fab, fba) = (eval(V, &m, &[], Vec3::Z, a, b, true).0, eval(V, &m, &[], Vec3::Z, b, a, true).0);
        let scale = fab.max_element().max(1e-3);
        assert!((fab - fba).abs().max_element() < 1e-4 * scale, "{a:?} {b:?}: {fab:?} against {fba:?}");
    }
}

/// ∫ f(wo, wi) cos θ_i dω_i over the hemisphere by the midpoint rule in (cos θ, φ).
fn albedo_by_quadrature(m: &shared::layout::Material, wo: Vec3) -> f64 {
    let (nt, np) = (1500, 600);
    let mut sum = 0f64;
    for i in 0..nt {
        let ct = (i as f64 + 0.5) / nt as f64;
        let st = (1.0 - ct * ct).sqrt();
        for j in 0..np {
            let phi = (j as f64 + 0.5) / np as f64 * 2.0 * PI;
            let wi = Vec3::new((st * phi.cos()) as f32, (st * phi.sin()) as f32, ct as f32);
            sum += eval(V, m, &[], Vec3::Z, wo, wi, true).0.x as f64 * ct;
        }
    }
    sum * 2.0 * PI / (nt * np) as f64
}

/// The furnace per BSDF: with a Fresnel term of 1, the mean sampled weight (the directional
/// albedo) matches the quadrature of f·cos, and is at most 1; GGX's single-scattering loss
/// grows with roughness and with the angle of incidence.
#[test]
fn rough_conductor_conserves_energy_and_its_samples_know_it() {
    let mut rng = Pcg64::seed_from_u64(11);
    let mut by_alpha = Vec::new();
    for alpha in [0.1f32, 0.4, 1.0] {
        let m = white(alpha);
        for theta in [0.0f32, 60.0, 85.0] {
            let wo = direction(theta, 30.0);
            let n = 400_000;
            let (mut s1, mut s2) = (0f64, 0f64);
            for _ in 0..n {
                let s = sample(V, &m, &[], Vec3::Z, wo, true, rng.random(), rng.random(), 0.5);
                let w = if s.pdf > 0.0 { s.weight.x as f64 } else { 0.0 };
                s1 += w;
                s2 += w * w;
            }
            let mean = s1 / n as f64;
            let se = ((s2 / n as f64 - mean * mean) / n as f64).sqrt();
            let quad = albedo_by_quadrature(&m, wo);
            eprintln!("α {alpha}, θ {theta}°: sampled albedo {mean:.5} ± {se:.5}, quadrature {quad:.5}");
            assert!(mean <= 1.0 + 4.0 * se && quad <= 1.0 + 1e-3, "α {alpha}, θ {theta}: energy created");
            assert!((mean - quad).abs() < 4.0 * se + 5e-3 * quad, "α {alpha}, θ {theta}: {mean} ± {se} against {quad}");
            if theta == 0.0 {
                by_alpha.push(mean);
            }
        }
    }
    // The loss grows with roughness. At normal incidence a reflection leaves the hemisphere when
    // its microfacet leans more than 45°, which GGX's visible normals do with probability
    // 1 / (1 + 1/α²): 1% at α 0.1, 14% at α 0.4 and half at α 1, before any masking.
    let lost = |a: f64| 1.0 / (1.0 + 1.0 / (a * a));
    for (i, a) in [0.1, 0.4, 1.0].into_iter().enumerate() {
        assert!(by_alpha[i] < 1.0 - lost(a) && by_alpha[i] > 1.0 - 2.5 * lost(a), "α {a}: {}", by_alpha[i]);
    }
}

#[test]
fn smooth_conductor_is_a_mirror() {
    let m = gold(0.0);
    assert!(is_delta(V, &m));
    assert!(!is_delta(V, &gold(0.2)));
    let wo = direction(40.0, 75.0);
    let s = sample(V, &m, &[], Vec3::Z, wo, true, 0.3, 0.7, 0.5);
    let mirror = Vec3::new(-wo.x, -wo.y, wo.z);
    assert!((s.wi - mirror).abs().max_element() < 1e-6, "{:?}", s.wi);
    assert_eq!(s.pdf, DELTA_PDF);
    let f = fresnel_conductor(wo.z, Vec3::new(0.143, 0.375, 1.442), Vec3::new(3.983, 2.386, 1.603));
    assert!((s.weight - f).abs().max_element() < 1e-6);
    // A delta lobe has nothing to evaluate.
    assert_eq!(eval(V, &m, &[], Vec3::Z, wo, mirror, true), (Vec3::ZERO, 0.0));
}

/// A closed box of perfect mirrors (Fresnel 1) that emit 1 everywhere, rendered without Russian
/// roulette: every path hits a wall B + 2 times and gathers 1 at each, so every pixel is B + 2
/// exactly. Rough, the walls lose energy and every pixel is below it.
#[test]
fn a_mirror_furnace_renders_its_known_value() {
    let tris = box_triangles(Vec3::splat(-1.0), Vec3::splat(1.0), true);
    let n = tris.len();
    let camera =
        Camera { eye: DVec3::new(0.1, 0.2, 0.5), target: DVec3::new(0.0, 0.0, -1.0), up: DVec3::Y, fov_deg: 60.0 };
    let settings = RenderSettings {
        width: 8,
        height: 8,
        spp: 4,
        max_bounces: 3,
        rr_start: 100,
        ..RenderSettings::with_camera(camera)
    };
    for (alpha, exact) in [(0.0f32, true), (0.5, false)] {
        let mirror = conductor(Vec3::ZERO, Vec3::ONE, alpha, Vec3::ONE);
        let scene = Scene::new(tris.clone(), vec![0; n], vec![mirror], vec!["mirror".into()]).unwrap();
        let c = compile(scene, BuildSettings::default());
        let r = cpu::render(&c, &settings, &|_, _| {}).unwrap();
        for p in r.mean() {
            if exact {
                assert!((p[0] - 5.0).abs() < 1e-4, "smooth mirror furnace: {p:?}, not 5");
            } else {
                assert!(p[0] > 1.0 && p[0] < 5.0, "rough mirror furnace: {p:?}");
            }
        }
    }
}

/// Scene files state conductors by named metal or by η and κ, with a roughness; `export` writes
/// them back so that loading the export gives the same materials.
#[test]
fn scene_files_state_conductors_and_export_keeps_them() {
    let dir = std::env::temp_dir().join(format!("kdtrace-conductors-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nusemtl a\nf 1 2 3\nusemtl b\nf 2 4 3\n";
    std::fs::write(dir.join("m.obj"), obj).unwrap();
    std::fs::write(dir.join("m.mtl"), "newmtl a\nKd 0.5 0.5 0.5\nnewmtl b\nKd 0.5 0.5 0.5\n").unwrap();
    let toml = "[materials.gold]\ntype = \"conductor\"\nmetal = \"Au\"\nalpha = 0.25\n\n\
                [materials.custom]\ntype = \"conductor\"\neta = [0.2, 0.9, 1.1]\nk = [3.9, 2.4, 2.1]\n\
                emission = [0, 0, 0]\n\n[[mesh]]\nfile = \"m.obj\"\nmaterials = { a = \"gold\", b = \"custom\" }\n";
    let path = dir.join("s.toml");
    std::fs::write(&path, toml).unwrap();
    let loaded = kdtrace::load(&path, BuildSettings::default()).unwrap();
    let mats = |l: &kdtrace::Loaded| {
        let s = &l.compiled.scene;
        (0..s.info.len()).map(|t| s.materials[s.info[t].material as usize]).collect::<Vec<_>>()
    };
    let m = mats(&loaded);
    let au = shared::material::CONDUCTOR_PRESETS[0];
    assert_eq!((m[0].kind, m[0].params.x), (shared::layout::MATERIAL_CONDUCTOR, 0.25));
    assert_eq!((m[0].eta.truncate(), m[0].k.truncate()), (Vec3::from(au.1), Vec3::from(au.2)));
    assert_eq!(
        (m[1].eta.truncate(), m[1].k.truncate(), m[1].params.x),
        (Vec3::new(0.2, 0.9, 1.1), Vec3::new(3.9, 2.4, 2.1), 0.0)
    );
    let out = dir.join("exported.toml");
    run::export(&path, &out);
    let again = kdtrace::load(&out, BuildSettings::default()).unwrap();
    assert_eq!(mats(&again), m);
}

#[test]
fn dielectric_fresnel_has_its_closed_forms() {
    use shared::material::fresnel_dielectric;
    // Normal incidence: ((η − 1)/(η + 1))², the same from either side.
    let (r, ct) = fresnel_dielectric(1.0, 1.5);
    assert!((r - 0.04).abs() < 1e-6 && (ct - 1.0).abs() < 1e-6);
    assert!((fresnel_dielectric(1.0, 1.0 / 1.5).0 - 0.04).abs() < 1e-6);
    // From outside it is the conductor formula with κ = 0.
    for c in [0.9f32, 0.5, 0.2, 0.05] {
        let (r, _) = fresnel_dielectric(c, 1.5);
        let f = fresnel_conductor(c, Vec3::splat(1.5), Vec3::ZERO).x;
        assert!((r - f).abs() < 1e-5, "cos {c}: {r} against {f}");
    }
    // From inside, beyond the critical angle (sin θ > 1/1.5), everything is reflected.
    let critical = (1.0f32 - (1.0 / 1.5f32).powi(2)).sqrt();
    assert_eq!(fresnel_dielectric(critical - 0.01, 1.0 / 1.5), (1.0, 0.0));
    assert!(fresnel_dielectric(critical + 0.01, 1.0 / 1.5).0 < 1.0);
}

/// Reflection with probability F, otherwise refraction by Snell's law with weight 1/η².
#[test]
fn smooth_dielectric_reflects_and_refracts_by_fresnel_and_snell() {
    use kdtrace::scene::dielectric;
    use shared::material::fresnel_dielectric;
    let glass = dielectric(1.5, 0.0, Vec3::ZERO);
    assert!(is_delta(V, &glass));
    // 30°: below the critical angle from inside too.
    let wo = direction(30.0, 20.0);
    for (front, eta) in [(true, 1.5f32), (false, 1.0 / 1.5)] {
        let (f, _) = fresnel_dielectric(wo.z, eta);
        let mut rng = Pcg64::seed_from_u64(5);
        let n = 200_000;
        let mut reflected = 0;
        for _ in 0..n {
            let s = sample(V, &glass, &[], Vec3::Z, wo, front, rng.random(), rng.random(), 0.5);
            assert_eq!(s.pdf, DELTA_PDF);
            if s.wi.z > 0.0 {
                reflected += 1;
                assert!((s.wi - Vec3::new(-wo.x, -wo.y, wo.z)).abs().max_element() < 1e-6);
                assert_eq!(s.weight, Vec3::ONE);
            } else {
                let (sin_i, sin_t) = ((1.0 - wo.z * wo.z).sqrt(), (1.0 - s.wi.z * s.wi.z).sqrt());
                assert!((sin_t * eta - sin_i).abs() < 1e-5, "Snell: {sin_i} against {eta}·{sin_t}");
                // In the plane of incidence, on the other side of the normal.
                assert!((s.wi.x * wo.y - s.wi.y * wo.x).abs() < 1e-6 && s.wi.x * wo.x < 0.0);
                assert!((s.weight.x - 1.0 / (eta * eta)).abs() < 1e-6);
            }
        }
        let share = reflected as f64 / n as f64;
        let se = (f as f64 * (1.0 - f as f64) / n as f64).sqrt();
        assert!((share - f as f64).abs() < 5.0 * se, "front {front}: reflected {share}, Fresnel {f}");
    }
}

/// The glass furnace: a closed glass sphere under a uniform sky of 1, rendered without Russian
/// roulette and with room for long internal paths. Radiance is conserved through the interfaces
/// (scaled by 1/η² going in and η² coming out), so every path brings 1. The facets trap a few
/// paths by total internal reflection for dozens of bounces (at a limit of 64, 0.5% were cut):
/// the limit here is 1000.
#[test]
fn a_glass_furnace_renders_one() {
    use kdtrace::scene::{dielectric, procedural::icosphere};
    let tris = icosphere(3);
    let n = tris.len();
    let scene = Scene::new(tris, vec![0; n], vec![dielectric(1.5, 0.0, Vec3::ZERO)], vec!["glass".into()]).unwrap();
    let c = compile(scene, BuildSettings::default());
    let camera = Camera { eye: DVec3::new(0.3, 0.2, 3.0), target: DVec3::ZERO, up: DVec3::Y, fov_deg: 40.0 };
    let s = RenderSettings {
        width: 16,
        height: 16,
        spp: 16,
        max_bounces: 1000,
        rr_start: 1000,
        environment: Vec3::ONE,
        ..RenderSettings::with_camera(camera)
    };
    let r = cpu::render(&c, &s, &|_, _| {}).unwrap();
    let px = r.mean();
    let mean = px.iter().map(|p| p[0] as f64).sum::<f64>() / px.len() as f64;
    assert!(px.iter().all(|p| p.iter().all(|c| (c - 1.0).abs() < 1e-5)), "mean {mean}: {px:?}");
}

/// MTL: `illum 5` (a mirror) becomes a smooth conductor reflecting `Ks` at normal incidence,
/// `illum 7` (glass) a dielectric of index `Ni`, the rest Lambertian: CornellBox-Sphere's spheres.
#[test]
fn mtl_mirrors_and_glass_become_conductors_and_dielectrics() {
    use shared::layout::{MATERIAL_CONDUCTOR, MATERIAL_DIELECTRIC, MATERIAL_DIFFUSE};
    let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/data/meshes/CornellBox-Sphere/CornellBox-Sphere.obj");
    let mesh = kdtrace::scene::obj::load_mesh(&path, &kdtrace::files::Disk).unwrap();
    let s = &mesh.scene;
    let by_name = |name: &str| s.materials[s.material_names.iter().position(|n| n == name).unwrap()];
    let (left, right, floor) = (by_name("leftSphere"), by_name("rightSphere"), by_name("floor"));
    assert_eq!((left.kind, left.params.x), (MATERIAL_CONDUCTOR, 0.0));
    // Ks 0.95 at normal incidence.
    let f0 = fresnel_conductor(1.0, left.eta.truncate(), left.k.truncate());
    assert!((f0 - Vec3::splat(0.95)).abs().max_element() < 1e-4, "{f0:?}");
    assert_eq!((right.kind, right.params.y), (MATERIAL_DIELECTRIC, 2.5));
    assert_eq!(floor.kind, MATERIAL_DIFFUSE);
}

/// `--aov albedo` and `--aov normal`: the first hit's albedo and camera-facing shading normal,
/// the same bits on the CPU and lavapipe; on the Cornell box the left wall's pixels are its red
/// albedo and the floor's normal is +y, and a gold block's albedo is gold's reflectance.
#[test]
fn albedo_and_normal_images_show_the_first_hit() {
    use kdtrace::{render::gpu, settings::Aov};
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let camera = Camera {
        eye: DVec3::new(0.278, 0.273, 0.8),
        target: DVec3::new(0.278, 0.273, 0.0),
        up: DVec3::Y,
        fov_deg: 39.3076,
    };
    let g = gpu::Gpu::lavapipe().unwrap();
    let c = kdtrace::load(&root.join("tests/data/cornell-metal/cornell-metal.toml"), BuildSettings::default()).unwrap();
    let c = &c.compiled;
    for aov in [Aov::Albedo, Aov::Normal] {
        let s = RenderSettings { width: 32, height: 32, spp: 4, aov, ..RenderSettings::with_camera(camera) };
        let a = cpu::render(c, &s, &|_, _| {}).unwrap();
        let b = g.render(c, &s, &|_, _| {}).unwrap();
        let bits = |r: &kdtrace::render::Rendered| {
            r.sum.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>()
        };
        assert!(bits(&a) == bits(&b), "{aov:?}: CPU and lavapipe differ");
        let px = a.mean();
        let at = |x: usize, y: usize| Vec3::from(px[y * 32 + x]);
        match aov {
            Aov::Albedo => {
                // The left wall (scenes/cornell-box.mtl `red`) and the gold block.
                assert!((at(1, 16) - Vec3::new(0.4749, 0.0451, 0.0491)).abs().max_element() < 1e-6, "{:?}", at(1, 16));
                let au = shared::material::CONDUCTOR_PRESETS[0];
                let gold = fresnel_conductor(1.0, Vec3::from(au.1), Vec3::from(au.2));
                let found = px.iter().any(|p| (Vec3::from(*p) - gold).abs().max_element() < 1e-5);
                assert!(found, "no pixel shows gold's albedo {gold:?}");
            }
            _ => {
                // The floor faces +y and the right wall −x (negative components are kept): each
                // covers many whole pixels; the left wall, not quite axis-aligned in Cornell's
                // data, faces about +x.
                let count = |n: Vec3| px.iter().filter(|p| (Vec3::from(**p) - n).abs().max_element() < 1e-6).count();
                let (floor, right) = (count(Vec3::Y), count(-Vec3::X));
                assert!(floor > 20 && right > 20, "floor {floor}, right wall {right} pixels");
                assert!(at(1, 16).x > 0.99, "left wall {:?}", at(1, 16));
            }
        }
    }
}

/// A `.kdc` keeps conductors and dielectrics: compiled and rendered, the gold box gives the
/// pixels its scene file gives.
#[test]
fn compiled_scenes_keep_their_materials() {
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let scene = root.join("tests/data/cornell-metal/cornell-metal.toml");
    let dir = std::env::temp_dir().join(format!("kdtrace-kdc-materials-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let kdc = dir.join("metal.kdc");
    let run = |args: &[&str]| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_kdtrace")).args(args).output().unwrap();
        assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
    };
    run(&["compile", scene.to_str().unwrap(), "--out", kdc.to_str().unwrap()]);
    let image = |input: &std::path::Path, name: &str| {
        let out = dir.join(name);
        run(&[
            "render",
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--width",
            "16",
            "--height",
            "16",
            "--spp",
            "4",
        ]);
        kdtrace::image::io::read_exr(&out).unwrap().2
    };
    let (a, b) = (image(&scene, "a.exr"), image(&kdc, "b.exr"));
    // A .kdc that lost the gold (read back as diffuse, say) would render the block grey.
    assert!(a == b, "the .kdc renders other pixels than its scene file");
}
