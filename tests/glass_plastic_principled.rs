//! The rough dielectric, plastic and principled materials' own properties, apart from their
//! sampling (χ² in `chi2.rs`): energy (a furnace per material: the sampled directional albedo
//! against the quadrature of f·|cos| over the sphere, never above 1), reciprocity of reflection
//! and the η² rule of refraction, and how scene files and MTL files state them.
#[path = "common/run.rs"]
mod run;
use kdtrace::{
    kdbuild::BuildSettings,
    scene::{coating::CoatingTable, dielectric, plastic, principled, Principled},
};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use shared::{
    features::Variant,
    glam::Vec3,
    layout::{Material, MATERIAL_DIELECTRIC, MATERIAL_PLASTIC, MATERIAL_PRINCIPLED},
    material::{eval, fresnel_dielectric, is_delta, rough_plastic_transmittance, sample, DELTA_PDF},
};
use std::f64::consts::PI;

const V: Variant = Variant::GENERIC_SPEC;

fn direction(theta_deg: f32, phi_deg: f32) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

/// ∫ f(wo, wi)·|cos θ_i|·(η² below the surface) dω_i over the whole sphere, by the midpoint
/// rule in (cos θ, φ), finer near the poles where the lobes of smooth-ish surfaces sit. The η²
/// turns transmitted radiance into transmitted energy (`eta` = the relative index).
fn energy_by_quadrature(m: &Material, wo: Vec3, front: bool, eta: f64) -> f64 {
    energy_by_quadrature_in(m, &[], wo, front, eta)
}

/// `energy_by_quadrature` with the texture buffer `words` (a rough plastic's table).
fn energy_by_quadrature_in(m: &Material, words: &[u32], wo: Vec3, front: bool, eta: f64) -> f64 {
    let (nt, np) = (3000, 1200);
    let mut sum = 0f64;
    for side in [1.0f64, -1.0] {
        for i in 0..nt {
            // cos θ = 1 − s², s uniform: points crowd toward the pole.
            let s = (i as f64 + 0.5) / nt as f64;
            let ct = 1.0 - s * s;
            let dct = 2.0 * s / nt as f64;
            let st = (1.0 - ct * ct).max(0.0).sqrt();
            for j in 0..np {
                let phi = (j as f64 + 0.5) / np as f64 * 2.0 * PI;
                let wi = Vec3::new((st * phi.cos()) as f32, (st * phi.sin()) as f32, (side * ct) as f32);
                let f = eval(V, m, words, Vec3::Z, wo, wi, front).0.x as f64;
                sum += f * ct * dct * if side < 0.0 { eta * eta } else { 1.0 };
            }
        }
    }
    sum * 2.0 * PI / np as f64
}

/// The mean sampled weight (with η² for transmission) and its standard error.
fn energy_by_sampling(m: &Material, wo: Vec3, front: bool, eta: f64, seed: u64) -> (f64, f64) {
    energy_by_sampling_in(m, &[], wo, front, eta, seed)
}

/// `energy_by_sampling` with the texture buffer `words` (a rough plastic's table).
fn energy_by_sampling_in(m: &Material, words: &[u32], wo: Vec3, front: bool, eta: f64, seed: u64) -> (f64, f64) {
    let mut rng = Pcg64::seed_from_u64(seed);
    let n = 300_000;
    let (mut s1, mut s2) = (0f64, 0f64);
    for _ in 0..n {
        let s = sample(V, m, words, Vec3::Z, wo, front, rng.random(), rng.random(), rng.random());
        let w = if s.pdf > 0.0 { s.weight.x as f64 * if s.wi.z < 0.0 { eta * eta } else { 1.0 } } else { 0.0 };
        s1 += w;
        s2 += w * w;
    }
    let mean = s1 / n as f64;
    (mean, ((s2 / n as f64 - mean * mean) / n as f64).sqrt())
}

/// The rough dielectric's furnace, entering and leaving: reflected plus transmitted energy is at
/// most 1, what sampling returns matches the quadrature, and the loss (the single-scattering
/// microfacet model's) grows with roughness.
#[test]
fn rough_dielectric_conserves_energy_and_its_samples_know_it() {
    let mut seed = 1;
    for front in [true, false] {
        let eta = if front { 1.5 } else { 1.0 / 1.5 };
        let mut by_alpha = Vec::new();
        for alpha in [0.2f32, 0.5, 1.0] {
            let m = dielectric(1.5, alpha, Vec3::ZERO);
            for theta in [0.0f32, 50.0, 80.0] {
                let wo = direction(theta, 40.0);
                let (mean, se) = energy_by_sampling(&m, wo, front, eta, seed);
                seed += 1;
                let quad = energy_by_quadrature(&m, wo, front, eta);
                eprintln!("front {front}, α {alpha}, θ {theta}°: sampled {mean:.5} ± {se:.5}, quadrature {quad:.5}");
                assert!(
                    mean <= 1.0 + 4.0 * se && quad <= 1.0 + 2e-3,
                    "front {front}, α {alpha}, θ {theta}: energy created"
                );
                assert!(
                    (mean - quad).abs() < 4.0 * se + 1e-2 * quad,
                    "front {front}, α {alpha}, θ {theta}: {mean} against {quad}"
                );
                if theta == 0.0 {
                    by_alpha.push(mean);
                }
            }
        }
        // At normal incidence: a few percent lost at α 0.2, more than half at α 1 (refractions
        // through steep microfacets that head back up, and masking).
        assert!(by_alpha[0] > 0.93 && by_alpha[0] > by_alpha[1] && by_alpha[1] > by_alpha[2], "{by_alpha:?}");
    }
}

/// Reflection is reciprocal, f(a, b) = f(b, a); refraction follows the η² rule of radiance,
/// f(b → a) = η² f(a → b) for a outside and b inside (η = η_inside / η_outside), as Veach's
/// generalised reciprocity f(a, b)/η_b² = f(b, a)/η_a² says.
#[test]
fn rough_dielectric_is_reciprocal_and_follows_the_eta_squared_rule() {
    let m = dielectric(1.5, 0.3, Vec3::ZERO);
    let mut rng = Pcg64::seed_from_u64(9);
    let mut refracting = 0;
    for _ in 0..20_000 {
        let a = direction(rng.random_range(0.0..85.0), rng.random_range(0.0..360.0));
        let b = direction(rng.random_range(0.0..85.0), rng.random_range(0.0..360.0));
        for front in [true, false] {
            let (fab, fba) = (eval(V, &m, &[], Vec3::Z, a, b, front).0.x, eval(V, &m, &[], Vec3::Z, b, a, front).0.x);
            assert!((fab - fba).abs() <= 5e-4 * fab.max(1e-3), "reflection {a:?} {b:?}: {fab} against {fba}");
        }
        // a outside (above +z), b inside (below): from inside, the shading normal is −z. Where
        // the value is tiny the microfacet is nearly grazing, F nearly 1, and 1 − F is f32
        // rounding: those pairs are left out.
        let below = Vec3::new(b.x, b.y, -b.z);
        let into = eval(V, &m, &[], Vec3::Z, a, below, true).0.x as f64;
        let out = eval(V, &m, &[], -Vec3::Z, below, a, false).0.x as f64;
        if into > 1e-2 {
            assert!((out - 2.25 * into).abs() <= 1e-3 * out, "{a:?} {below:?}: {out} against 2.25·{into}");
            refracting += 1;
        }
    }
    assert!(refracting > 1000, "only {refracting} pairs refract");
}

/// A smooth dielectric stays a delta; a rough one is not, and transmits under the surface.
#[test]
fn roughness_makes_glass_glossy() {
    let (smooth, rough) = (dielectric(1.5, 0.0, Vec3::ZERO), dielectric(1.5, 0.3, Vec3::ZERO));
    assert!(is_delta(V, &smooth) && !is_delta(V, &rough));
    let wo = direction(20.0, 0.0);
    let mut rng = Pcg64::seed_from_u64(4);
    let (mut up, mut down) = (0, 0);
    for _ in 0..10_000 {
        let s = sample(V, &rough, &[], Vec3::Z, wo, true, rng.random(), rng.random(), rng.random());
        assert!(s.pdf < DELTA_PDF);
        if s.pdf == 0.0 {
            // A microfacet reflection below the surface, or a refraction above it: no direction.
            continue;
        }
        if s.wi.z > 0.0 {
            up += 1;
        } else {
            down += 1;
        }
    }
    // About 4% reflected at 20° from outside.
    assert!(up > 200 && up < 700 && down > 9000 && up + down > 9900, "{up} reflected, {down} refracted");
}

/// Plastic: the coating's mirror reflects F(θ), the base the rest of what it gets back, so
/// that a white base under the coating returns at most 1, close to it (what the coating's
/// inside reflects back is lost to the base again and again, F_dr's series); the mirror part is
/// exactly Fresnel's.
#[test]
fn plastic_conserves_energy_and_its_coating_reflects_by_fresnel() {
    let white = plastic(Vec3::ONE, 1.5, 0.0, Vec3::ZERO);
    for (k, theta) in [0.0f32, 45.0, 80.0].into_iter().enumerate() {
        let wo = direction(theta, 10.0);
        let (mean, se) = energy_by_sampling(&white, wo, true, 1.5, 50 + k as u64);
        // The base's share by quadrature, plus the mirror's F.
        let quad = energy_by_quadrature(&white, wo, true, 1.5) + fresnel_dielectric(wo.z, 1.5).0 as f64;
        eprintln!("plastic θ {theta}°: sampled {mean:.5} ± {se:.5}, quadrature {quad:.5}");
        // Exactly 1 for exact diffuse Fresnel reflectances (1 − F_dr,ext = η²(1 − F_dr,int));
        // the fits Mitsuba uses for F_dr are good to 0.1-0.6%.
        assert!(mean <= 1.006 + 4.0 * se && quad <= 1.006, "θ {theta}: energy created");
        assert!((mean - quad).abs() < 4.0 * se + 5e-3, "θ {theta}: {mean} against {quad}");
        assert!(quad > 0.98, "θ {theta}: a white plastic returns only {quad}");
    }
    // A mirror sample carries F / p_specular: averaged over the picks, F.
    let wo = direction(60.0, 0.0);
    let mut rng = Pcg64::seed_from_u64(3);
    let (mut mirror, n) = (0f64, 200_000);
    for _ in 0..n {
        let s = sample(V, &white, &[], Vec3::Z, wo, true, rng.random(), rng.random(), rng.random());
        if s.pdf == DELTA_PDF {
            assert!((s.wi - Vec3::new(-wo.x, -wo.y, wo.z)).abs().max_element() < 1e-6);
            mirror += s.weight.x as f64;
        }
    }
    let f = fresnel_dielectric(wo.z, 1.5).0 as f64;
    assert!((mirror / n as f64 - f).abs() < 0.02 * f, "mirror energy {} against F {f}", mirror / n as f64);
}

/// The rough plastic (Mitsuba's `roughplastic`): a white base under a rough coating returns at
/// most 1 (up to what the single-scattering coating and the table's quadratures leave), and its
/// samples match the quadrature of f·cos.
#[test]
fn rough_plastic_conserves_energy_and_its_samples_know_it() {
    let mut seed = 90;
    // The single-scattering coating loses what its microfacets shadow, more the rougher it is
    // (Mitsuba's model: its internal reflectance drops with the shadowed part of its total
    // internal reflection, and the base's factor 1/(η²(1 − R_int)) with it).
    for (alpha, least) in [(0.1f32, 0.85), (0.4, 0.5)] {
        let white = plastic(Vec3::ONE, 1.5, alpha, Vec3::ZERO);
        let words = CoatingTable::new(alpha, 1.5).words();
        for theta in [0.0f32, 45.0, 80.0] {
            let wo = direction(theta, 10.0);
            let (mean, se) = energy_by_sampling_in(&white, &words, wo, true, 1.5, seed);
            seed += 1;
            let quad = energy_by_quadrature_in(&white, &words, wo, true, 1.5);
            eprintln!("rough plastic α {alpha}, θ {theta}°: sampled {mean:.5} ± {se:.5}, quadrature {quad:.5}");
            assert!(mean <= 1.01 + 4.0 * se && quad <= 1.01, "α {alpha}, θ {theta}: energy created");
            assert!((mean - quad).abs() < 4.0 * se + 5e-3, "α {alpha}, θ {theta}: {mean} against {quad}");
            assert!(quad > least, "α {alpha}, θ {theta}: a white rough plastic returns only {quad}");
        }
    }
}

/// The rough coating's table: t(1) is 1 − F(0°) for a nearly smooth coating, t stays within
/// (0, 1] and grows with μ (but for a dip of under 1% at the grazing end, where the visible
/// normals of Mitsuba's single-scattering model turn toward the direction); the shader's lookup returns the table's points and interpolates
/// between them; the internal reflectance matches a brute-force quadrature of the microfacet
/// reflection over the sphere at the same cosines.
#[test]
fn rough_plastic_table_is_the_interface_transmittance() {
    let smooth = CoatingTable::new(0.01, 1.5);
    let f0 = fresnel_dielectric(1.0, 1.5).0 as f64;
    let t1 = *smooth.transmittance.last().unwrap();
    assert!((t1 - (1.0 - f0)).abs() < 1e-3, "t(1) = {t1} against 1 − F = {}", 1.0 - f0);
    for alpha in [0.1f32, 0.2, 0.5] {
        let table = CoatingTable::new(alpha, 1.5);
        let t = &table.transmittance;
        assert!(t.iter().skip(1).all(|&v| v > 0.0 && v <= 1.0), "α {alpha}: {t:?}");
        assert!(t[3..].windows(2).all(|w| w[1] >= w[0]), "α {alpha}: not monotone: {t:?}");
        assert!(t[..4].iter().all(|&v| v >= 0.99 * t[0]), "α {alpha}: grazing dip: {t:?}");
        // The lookup, at the points and halfway.
        let words = table.words();
        for k in 0..63 {
            let mu = k as f32 / 63.0;
            let at = rough_plastic_transmittance(&words, 0, mu);
            assert!((at as f64 - t[k]).abs() < 1e-6, "α {alpha}: t({mu}) = {at} against {}", t[k]);
            let mid = rough_plastic_transmittance(&words, 0, (k as f32 + 0.5) / 63.0) as f64;
            assert!((mid - 0.5 * (t[k] + t[k + 1])).abs() < 1e-6, "α {alpha}, k {k}: {mid}");
        }
        // Brute force: R(μ) = ∫ F(i·h, 1/η)·D(h)·G1(o)G1(i)/(4 μ) dω_i by the midpoint rule.
        let a2 = alpha as f64 * alpha as f64;
        let g1 = |z: f64| 2.0 / (1.0 + (1.0 + a2 * (1.0 - z * z) / (z * z)).sqrt());
        let fresnel = |c: f64| {
            let eta = 1.0 / 1.5f64;
            let st2 = (1.0 - c * c) / (eta * eta);
            if st2 >= 1.0 {
                return 1.0;
            }
            let ct = (1.0 - st2).sqrt();
            let rs = (c - eta * ct) / (c + eta * ct);
            let rp = (eta * c - ct) / (eta * c + ct);
            0.5 * (rs * rs + rp * rp)
        };
        let reflectance = |mu: f64| {
            let o = [(1.0 - mu * mu).sqrt(), 0.0, mu];
            let (nt, np) = (1500, 600);
            let mut sum = 0.0;
            for i in 0..nt {
                let s = (i as f64 + 0.5) / nt as f64;
                let ct = 1.0 - s * s;
                let dct = 2.0 * s / nt as f64;
                let st = (1.0 - ct * ct).max(0.0).sqrt();
                for j in 0..np {
                    let phi = (j as f64 + 0.5) / np as f64 * 2.0 * PI;
                    let wi = [st * phi.cos(), st * phi.sin(), ct];
                    let h = [o[0] + wi[0], o[1] + wi[1], o[2] + wi[2]];
                    let l = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
                    let h = [h[0] / l, h[1] / l, h[2] / l];
                    let t = a2 * h[2] * h[2] + h[0] * h[0] + h[1] * h[1];
                    let d = a2 / (PI * t * t);
                    let c = o[0] * h[0] + o[1] * h[1] + o[2] * h[2];
                    // f·cos θ_i = F·D·G1(o)·G1(i) / (4 μ).
                    sum += fresnel(c) * d * g1(mu) * g1(ct) / (4.0 * mu) * dct;
                }
            }
            sum * 2.0 * PI / np as f64
        };
        let mus = kdtrace::scene::coating::table_cosines();
        let brute = 2.0 * mus.iter().skip(1).map(|&mu| reflectance(mu) * mu).sum::<f64>() / mus.len() as f64;
        let r = table.internal_reflectance;
        eprintln!("α {alpha}: internal reflectance {r:.5}, brute force {brute:.5}; t(1) {:.5}", t[63]);
        assert!((r - brute).abs() < 4e-3, "α {alpha}: internal reflectance {r} against {brute}");
    }
}

fn gltf(base: Vec3, metallic: f32, roughness: f32, transmission: f32) -> Material {
    principled(&Principled { base_color: base, metallic, roughness, transmission, ior: 1.5 }, Vec3::ZERO)
}

/// The principled model's furnace over its parameters: a white base colour returns at most 1 at
/// every angle, metal or dielectric, opaque or transmissive; samples match the quadrature.
#[test]
fn principled_conserves_energy_and_its_samples_know_it() {
    let mut seed = 70;
    for (metallic, roughness, transmission) in
        [(0.0f32, 0.3f32, 0.0f32), (0.0, 0.7, 0.0), (1.0, 0.3, 0.0), (1.0, 1.0, 0.0), (0.5, 0.5, 0.5), (0.0, 0.4, 1.0)]
    {
        let m = gltf(Vec3::ONE, metallic, roughness, transmission);
        for theta in [0.0f32, 60.0, 85.0] {
            let wo = direction(theta, 25.0);
            let (mean, se) = energy_by_sampling(&m, wo, true, 1.5, seed);
            seed += 1;
            let quad = energy_by_quadrature(&m, wo, true, 1.5);
            let what = format!("metallic {metallic}, roughness {roughness}, transmission {transmission}, θ {theta}°");
            eprintln!("{what}: sampled {mean:.5} ± {se:.5}, quadrature {quad:.5}");
            assert!(mean <= 1.0 + 4.0 * se && quad <= 1.0 + 2e-3, "{what}: energy created");
            assert!((mean - quad).abs() < 4.0 * se + 1e-2 * quad, "{what}: {mean} against {quad}");
            // Not dead: at 85° a rough dielectric base gets only the 39% the coat lets in.
            assert!(quad > 0.3, "{what}: returns only {quad}");
        }
    }
}

/// Under a clear coat the model still returns at most 1 with a white base, at every angle, and
/// its samples match the quadrature.
#[test]
fn clear_coated_principled_conserves_energy() {
    let mut seed = 170;
    for (metallic, roughness, transmission, coat, coat_roughness) in
        [(0.0f32, 0.7f32, 0.0f32, 1.0f32, 0.3f32), (1.0, 0.4, 0.0, 1.0, 0.5), (0.3, 0.5, 0.6, 0.6, 0.3)]
    {
        let m = kdtrace::scene::clearcoat(gltf(Vec3::ONE, metallic, roughness, transmission), coat, coat_roughness);
        for theta in [0.0f32, 60.0, 85.0] {
            let wo = direction(theta, 25.0);
            let (mean, se) = energy_by_sampling(&m, wo, true, 1.5, seed);
            seed += 1;
            let quad = energy_by_quadrature(&m, wo, true, 1.5);
            let bare = energy_by_quadrature(&gltf(Vec3::ONE, metallic, roughness, transmission), wo, true, 1.5);
            let what = format!(
                "metallic {metallic}, roughness {roughness}, transmission {transmission}, coat {coat} \
                 ({coat_roughness}), θ {theta}°"
            );
            eprintln!("{what}: sampled {mean:.5} ± {se:.5}, quadrature {quad:.5}, uncoated {bare:.5}");
            assert!(mean <= 1.0 + 4.0 * se && quad <= 1.0 + 2e-3, "{what}: energy created");
            assert!((mean - quad).abs() < 4.0 * se + 1e-2 * quad, "{what}: {mean} against {quad}");
            // Not dead. At grazing angles the base keeps 1 − F(θ) while a rough coat's microfacets,
            // seen more head-on, reflect less than F(θ): a metal under a rough coat at 85°
            // returns about half (the glTF sketch weighs the base the same way).
            assert!(quad > 0.3, "{what}: returns only {quad} (uncoated {bare})");
        }
    }
}

/// A metal's colour is its base colour at normal incidence (Schlick's f0): red and blue
/// reflect in the base's ratio.
#[test]
fn principled_metal_takes_its_colour_from_the_base() {
    let channel = |b: f32| energy_by_quadrature(&gltf(Vec3::splat(b), 1.0, 0.3, 0.0), Vec3::Z, true, 1.5);
    let (r, b) = (channel(0.9), channel(0.2));
    assert!((r / b / 4.5 - 1.0).abs() < 0.05, "red {r} and blue {b} reflect unlike the base's ratio 4.5");
    assert!(r < 0.9 && r > 0.8, "red {r}");
}

fn write(dir: &std::path::Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("kdtrace-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn materials_of(l: &kdtrace::Loaded) -> Vec<Material> {
    let s = &l.compiled.scene;
    (0..s.info.len()).map(|t| s.materials[s.info[t].material as usize]).collect()
}

/// Scene files state rough glass, plastic and principled materials with the schema;
/// `export` writes them back so that loading the export gives the same materials.
#[test]
fn scene_files_state_the_new_materials_and_export_keeps_them() {
    let dir = temp_dir("pbr-scene");
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 2 1 0\nusemtl a\nf 1 2 3\nusemtl b\nf 2 4 3\nusemtl c\nf 2 5 4\n";
    write(&dir, "m.obj", obj);
    write(&dir, "m.mtl", "newmtl a\nKd 0.5 0.5 0.5\nnewmtl b\nKd 0.5 0.5 0.5\nnewmtl c\nKd 0.5 0.5 0.5\n");
    let toml = "[materials.glass]\ntype = \"dielectric\"\nior = 1.33\nalpha = 0.15\n\n\
                [materials.red]\ntype = \"plastic\"\nalbedo = [0.5, 0.1, 0.1]\nior = 1.6\n\n\
                [materials.paint]\ntype = \"principled\"\nbase_color = [0.8, 0.2, 0.1]\nmetallic = 0.25\n\
                roughness = 0.5\ntransmission = 0.1\nior = 1.45\nclearcoat = 0.7\nclearcoat_roughness = 0.5\n\n\
                [[mesh]]\nfile = \"m.obj\"\nmaterials = { a = \"glass\", b = \"red\", c = \"paint\" }\n";
    let path = write(&dir, "s.toml", toml);
    let loaded = kdtrace::load(&path, BuildSettings::default()).unwrap();
    let m = materials_of(&loaded);
    assert_eq!((m[0].kind, m[0].params.x, m[0].params.y), (MATERIAL_DIELECTRIC, 0.15, 1.33));
    assert_eq!((m[1].kind, m[1].albedo.truncate(), m[1].params.y), (MATERIAL_PLASTIC, Vec3::new(0.5, 0.1, 0.1), 1.6));
    assert_eq!(m[2].kind, MATERIAL_PRINCIPLED);
    assert_eq!(m[2].albedo.truncate(), Vec3::new(0.8, 0.2, 0.1));
    // α = roughness².
    assert_eq!(m[2].params.to_array(), [0.25, 1.45, 0.25, 0.1]);
    // The clear coat's factor and α = roughness².
    assert_eq!((m[2].eta.x, m[2].eta.y), (0.7, 0.25));
    let out = dir.join("exported.toml");
    run::export(&path, &out);
    assert_eq!(materials_of(&kdtrace::load(&out, BuildSettings::default()).unwrap()), m);
}

/// MTL: `Ks` with `Ns` becomes a principled dielectric whose specular lobe reflects Ks at normal
/// incidence with the GGX α of the Phong exponent, over `Kd`; the PBR extension's `Pr` and `Pm`
/// give roughness and metallic; a material without them stays diffuse.
#[test]
fn mtl_specular_and_pbr_keys_become_principled_materials() {
    let dir = temp_dir("pbr-mtl");
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 2 1 0\nusemtl glossy\nf 1 2 3\nusemtl pbr\nf 2 4 3\nusemtl matte\nf 2 5 4\n";
    write(&dir, "m.obj", obj);
    let mtl = "newmtl glossy\nKd 0.4 0.5 0.6\nKs 0.3 0.3 0.3\nNs 98\nillum 2\n\
               newmtl pbr\nKd 0.9 0.8 0.1\nPr 0.35\nPm 1\nNi 1.7\n\
               newmtl matte\nKd 0.2 0.2 0.2\nKs 0 0 0\nNs 10\n";
    write(&dir, "m.mtl", mtl);
    let mesh = kdtrace::scene::obj::load_mesh(&dir.join("m.obj"), &kdtrace::files::Disk).unwrap();
    let s = &mesh.scene;
    let by_name = |name: &str| s.materials[s.material_names.iter().position(|n| n == name).unwrap()];
    let glossy = by_name("glossy");
    assert_eq!(
        (glossy.kind, glossy.albedo.truncate(), glossy.params.z),
        (MATERIAL_PRINCIPLED, Vec3::new(0.4, 0.5, 0.6), 0.0)
    );
    // Reflects Ks = 0.3 at normal incidence.
    let f0 = fresnel_dielectric(1.0, glossy.params.y).0;
    assert!((f0 - 0.3).abs() < 1e-5, "F0 {f0}");
    // α = √(2 / (Ns + 2)) = √0.02.
    assert!((glossy.params.x - 0.02f32.sqrt()).abs() < 1e-6, "α {}", glossy.params.x);
    let pbr = by_name("pbr");
    assert_eq!(pbr.kind, MATERIAL_PRINCIPLED);
    assert!((pbr.params.x - 0.35 * 0.35).abs() < 1e-7);
    assert_eq!((pbr.params.y, pbr.params.z, pbr.params.w), (1.7, 1.0, 0.0));
    assert_eq!(by_name("matte").kind, shared::layout::MATERIAL_DIFFUSE);
    // Out of range: the file and line.
    write(&dir, "m.mtl", "newmtl glossy\nKd 0.4 0.5 0.6\nPr 1.5\n");
    let e = kdtrace::scene::obj::load_mesh(&dir.join("m.obj"), &kdtrace::files::Disk).err().unwrap();
    let e = format!("{e:#}");
    assert!(e.contains("m.mtl:3") && e.contains("Pr needs one number"), "{e}");
}
