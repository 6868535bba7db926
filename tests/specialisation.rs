//! Specialised variants give the generic code's image bit for bit. Each scene below leaves out a
//! different part of the feature set (`shared::features`), checked first, so every bit is off in
//! some case: emitters, many emitters, the environment, indirect light, each material kind (a
//! scene of metals alone, smooth and rough, has no diffuse), the light subpaths' connections
//! (`shared::connection`; three scenes run them, with one emitter or several, with and without a
//! sky, and one without them); and the bounce limit and roulette start are constants in the
//! GPU's specialised pipelines. Per case, the CPU's
//! monomorphised variant equals its generic code, and on lavapipe the specialised pipeline and the
//! generic one both equal the CPU (sums, squared sums and primary hits).
#[path = "common/paths.rs"]
mod paths;
use kdtrace::{
    compile,
    kdbuild::BuildSettings,
    load,
    render::{cpu, features, gpu, Compiled, Rendered},
    scene::{
        conductor, dielectric, diffuse, plastic, principled,
        procedural::{box_triangles, quad},
        EnvironmentMap, Principled, PunctualLight, Scene,
    },
    settings::{camera::Camera, Connect, RenderSettings},
};
use paths::mesh;
use shared::features::{
    FEATURES_ALL, FEATURE_CONDUCTOR, FEATURE_CONNECT, FEATURE_DIELECTRIC, FEATURE_DIFFUSE, FEATURE_EMITTERS,
    FEATURE_ENVIRONMENT, FEATURE_ENVIRONMENT_MAP, FEATURE_INDIRECT, FEATURE_MANY_EMITTERS, FEATURE_PLASTIC,
    FEATURE_PRINCIPLED, FEATURE_PUNCTUAL,
};
use shared::glam::{DVec3, Vec3, Vec4};
use shared::integrator::PixelSpan;
use shared::layout::Material;
use shared::material::CONDUCTOR_PRESETS;

fn no_progress(_: u64, _: u64) {}

fn material(albedo: f32, emission: f32) -> Material {
    diffuse(Vec3::splat(albedo), Vec3::splat(emission))
}

/// A floor and a block under an optional lamp of one triangle (facing down) and optional sky.
fn lamp_and_block(lamp: bool) -> Compiled {
    let mut tris: Vec<_> = quad(
        Vec3::new(-2.0, 0.0, 2.0),
        Vec3::new(2.0, 0.0, 2.0),
        Vec3::new(2.0, 0.0, -2.0),
        Vec3::new(-2.0, 0.0, -2.0),
    )
    .to_vec();
    tris.extend(box_triangles(Vec3::new(-0.5, 0.0, -0.5), Vec3::new(0.5, 1.0, 0.5), false));
    let mut material_of = vec![0; tris.len()];
    if lamp {
        tris.extend(
            quad(
                Vec3::new(-0.3, 2.0, -0.3),
                Vec3::new(0.3, 2.0, -0.3),
                Vec3::new(0.3, 2.0, 0.3),
                Vec3::new(-0.3, 2.0, 0.3),
            )[..1]
                .iter()
                .copied(),
        );
        material_of.push(1);
    }
    let scene = Scene::new(
        tris,
        material_of,
        vec![material(0.7, 0.0), material(0.5, 20.0)],
        vec!["floor".into(), "lamp".into()],
    )
    .unwrap();
    compile(scene, BuildSettings::default())
}

/// A small non-uniform sky: brighter toward +Y, a bright patch, rotated.
fn sky_map() -> EnvironmentMap {
    let (w, h) = (12u32, 6u32);
    let texels = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let b = if (x, y) == (3, 1) { 20.0 } else { 0.3 + 0.2 * (h - y) as f32 + 0.05 * x as f32 };
            [b, 0.8 * b, 0.6 * b]
        })
        .collect();
    EnvironmentMap::new(w, h, texels, 1.2, [10.0, 35.0, 0.0], "sky".into()).unwrap()
}

/// `c` with an environment map and punctual lights added.
fn with_lights(mut c: Compiled, map: bool, punctual: bool) -> Compiled {
    if map {
        c.scene.environment_map = Some(sky_map());
    }
    if punctual {
        c.scene.punctual_lights = vec![
            PunctualLight::point(DVec3::new(1.0, 1.5, 1.0), Vec3::new(1.0, 0.9, 0.8), 3.0),
            PunctualLight::spot(DVec3::new(-1.0, 2.0, 0.5), DVec3::new(0.4, -1.0, -0.2), Vec3::ONE, 8.0, 0.2, 0.5),
            PunctualLight::directional(DVec3::new(-0.3, -1.0, -0.4), Vec3::new(0.5, 0.6, 0.9), 1.5),
        ];
    }
    c.prepare_emitters();
    c
}

/// `lamp_and_block(true)` in metal: a smooth silver floor, a gold block, the lamp a silver that
/// emits; `alpha` the block's and the lamp's roughness.
fn metals(alpha: f32) -> Compiled {
    let c = lamp_and_block(true);
    let mut scene = c.scene;
    let (silver, gold) = (CONDUCTOR_PRESETS[1], CONDUCTOR_PRESETS[0]);
    scene.materials[0] = conductor(Vec3::from(silver.1), Vec3::from(silver.2), 0.0, Vec3::ZERO);
    scene.materials[1] = conductor(Vec3::from(silver.1), Vec3::from(silver.2), alpha, Vec3::splat(20.0));
    scene.materials.push(conductor(Vec3::from(gold.1), Vec3::from(gold.2), alpha, Vec3::ZERO));
    // The block's twelve triangles follow the floor's two.
    for t in &mut scene.info[2..14] {
        t.material = 2;
    }
    compile(scene, BuildSettings::default())
}

/// `lamp_and_block(true)` with its block made of `block`, and the floor of `floor` if given.
fn block_of(block: Material, floor: Option<Material>) -> Compiled {
    let mut scene = lamp_and_block(true).scene;
    scene.materials.push(block);
    for t in &mut scene.info[2..14] {
        t.material = 2;
    }
    if let Some(f) = floor {
        scene.materials[0] = f;
    }
    compile(scene, BuildSettings::default())
}

/// A principled material.
fn gltf(base: f32, metallic: f32, roughness: f32, transmission: f32) -> Material {
    let p = Principled { base_color: Vec3::new(base, 0.6, 0.4), metallic, roughness, transmission, ior: 1.5 };
    principled(&p, Vec3::ZERO)
}

fn cornell(albedo_scale: f32) -> Compiled {
    let mut l = load(&mesh("CornellBox-Original/CornellBox-Original.obj"), BuildSettings::default()).unwrap();
    for m in &mut l.compiled.scene.materials {
        m.albedo *= Vec4::new(albedo_scale, albedo_scale, albedo_scale, 1.0);
    }
    l.compiled
}

/// Path tracing alone (`--connect off`): the cases that connect light subpaths say so with
/// `connecting`.
fn settings(eye: DVec3, target: DVec3, sky: f32, bounces: u32) -> RenderSettings {
    let camera = Camera { eye, target, up: DVec3::Y, fov_deg: 45.0 };
    RenderSettings {
        width: 20,
        height: 16,
        spp: 4,
        max_bounces: bounces,
        rr_start: 2,
        seed: 7,
        environment: Vec3::splat(sky),
        connect: Connect::Off,
        ..RenderSettings::with_camera(camera)
    }
}

/// `s` with light subpaths connected to the eye vertices (`--connect on`).
fn connecting(s: RenderSettings) -> RenderSettings {
    RenderSettings { connect: Connect::On, ..s }
}

fn same(a: &Rendered, b: &Rendered) -> bool {
    let bits = |v: &[Vec4]| v.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
    bits(&a.sum) == bits(&b.sum) && bits(&a.sum_sq) == bits(&b.sum_sq) && a.primary == b.primary
}

/// A scene, its settings and the feature set that analysis must find for it.
type Case = (&'static str, Compiled, RenderSettings, u32);

fn cases() -> Vec<Case> {
    let outside = (DVec3::new(0.0, 2.5, 5.0), DVec3::new(0.0, 0.5, 0.0));
    let box_view = (DVec3::new(0.0, 1.0, 3.4), DVec3::new(0.0, 1.0, 0.0));
    vec![
        (
            "Cornell box",
            cornell(1.0),
            connecting(settings(box_view.0, box_view.1, 0.0, 4)),
            FEATURE_EMITTERS | FEATURE_MANY_EMITTERS | FEATURE_DIFFUSE | FEATURE_INDIRECT | FEATURE_CONNECT,
        ),
        (
            "Cornell box, path tracing alone",
            cornell(1.0),
            settings(box_view.0, box_view.1, 0.0, 4),
            FEATURE_EMITTERS | FEATURE_MANY_EMITTERS | FEATURE_DIFFUSE | FEATURE_INDIRECT,
        ),
        (
            "Cornell box, direct light only",
            cornell(1.0),
            settings(box_view.0, box_view.1, 0.0, 0),
            FEATURE_EMITTERS | FEATURE_MANY_EMITTERS | FEATURE_DIFFUSE | FEATURE_INDIRECT,
        ),
        (
            "black Cornell box",
            cornell(0.0),
            settings(box_view.0, box_view.1, 0.0, 4),
            FEATURE_EMITTERS | FEATURE_MANY_EMITTERS | FEATURE_DIFFUSE,
        ),
        (
            "one lamp",
            lamp_and_block(true),
            connecting(settings(outside.0, outside.1, 0.0, 3)),
            FEATURE_EMITTERS | FEATURE_DIFFUSE | FEATURE_INDIRECT | FEATURE_CONNECT,
        ),
        (
            "one lamp under a sky",
            lamp_and_block(true),
            connecting(settings(outside.0, outside.1, 0.4, 3)),
            FEATURE_EMITTERS | FEATURE_ENVIRONMENT | FEATURE_DIFFUSE | FEATURE_INDIRECT | FEATURE_CONNECT,
        ),
        (
            "sky only",
            lamp_and_block(false),
            settings(outside.0, outside.1, 0.8, 3),
            FEATURE_ENVIRONMENT | FEATURE_DIFFUSE | FEATURE_INDIRECT,
        ),
        ("no light at all", lamp_and_block(false), settings(outside.0, outside.1, 0.0, 3), FEATURE_DIFFUSE),
        (
            "smooth metals",
            metals(0.0),
            settings(outside.0, outside.1, 0.4, 3),
            FEATURE_EMITTERS | FEATURE_ENVIRONMENT | FEATURE_CONDUCTOR | FEATURE_INDIRECT,
        ),
        (
            "rough metals",
            metals(0.3),
            settings(outside.0, outside.1, 0.0, 3),
            FEATURE_EMITTERS | FEATURE_CONDUCTOR | FEATURE_INDIRECT,
        ),
        (
            "glass",
            block_of(dielectric(1.5, 0.0, Vec3::ZERO), None),
            settings(outside.0, outside.1, 0.3, 4),
            FEATURE_EMITTERS | FEATURE_ENVIRONMENT | FEATURE_DIFFUSE | FEATURE_DIELECTRIC | FEATURE_INDIRECT,
        ),
        (
            "rough glass",
            block_of(dielectric(1.5, 0.3, Vec3::ZERO), None),
            settings(outside.0, outside.1, 0.3, 4),
            FEATURE_EMITTERS | FEATURE_ENVIRONMENT | FEATURE_DIFFUSE | FEATURE_DIELECTRIC | FEATURE_INDIRECT,
        ),
        (
            "plastic",
            block_of(plastic(Vec3::new(0.7, 0.2, 0.1), 1.5, 0.0, Vec3::ZERO), None),
            settings(outside.0, outside.1, 0.0, 3),
            FEATURE_EMITTERS | FEATURE_DIFFUSE | FEATURE_PLASTIC | FEATURE_INDIRECT,
        ),
        (
            "principled metal floor, transmissive block",
            block_of(gltf(0.9, 0.0, 0.2, 1.0), Some(gltf(0.8, 1.0, 0.4, 0.0))),
            settings(outside.0, outside.1, 0.3, 4),
            FEATURE_EMITTERS | FEATURE_ENVIRONMENT | FEATURE_DIFFUSE | FEATURE_PRINCIPLED | FEATURE_INDIRECT,
        ),
        (
            "rough plastic",
            block_of(plastic(Vec3::new(0.7, 0.2, 0.1), 1.5, 0.25, Vec3::ZERO), None),
            settings(outside.0, outside.1, 0.3, 4),
            FEATURE_EMITTERS | FEATURE_ENVIRONMENT | FEATURE_DIFFUSE | FEATURE_PLASTIC | FEATURE_INDIRECT,
        ),
        (
            "environment map alone",
            with_lights(lamp_and_block(false), true, false),
            settings(outside.0, outside.1, 0.0, 3),
            FEATURE_DIFFUSE | FEATURE_INDIRECT | FEATURE_ENVIRONMENT_MAP,
        ),
        (
            "a lamp and an environment map",
            with_lights(lamp_and_block(true), true, false),
            settings(outside.0, outside.1, 0.0, 3),
            FEATURE_EMITTERS | FEATURE_MANY_EMITTERS | FEATURE_DIFFUSE | FEATURE_INDIRECT | FEATURE_ENVIRONMENT_MAP,
        ),
        (
            "punctual lights",
            with_lights(lamp_and_block(false), false, true),
            settings(outside.0, outside.1, 0.0, 3),
            FEATURE_MANY_EMITTERS | FEATURE_DIFFUSE | FEATURE_INDIRECT | FEATURE_PUNCTUAL,
        ),
        (
            "every kind of light, rough metals",
            with_lights(metals(0.3), true, true),
            settings(outside.0, outside.1, 0.0, 3),
            FEATURE_EMITTERS
                | FEATURE_MANY_EMITTERS
                | FEATURE_CONDUCTOR
                | FEATURE_INDIRECT
                | FEATURE_ENVIRONMENT_MAP
                | FEATURE_PUNCTUAL,
        ),
        (
            "a plastic block under a map and a spot",
            with_lights(block_of(plastic(Vec3::new(0.7, 0.2, 0.1), 1.5, 0.25, Vec3::ZERO), None), true, true),
            settings(outside.0, outside.1, 0.0, 3),
            FEATURE_EMITTERS
                | FEATURE_MANY_EMITTERS
                | FEATURE_DIFFUSE
                | FEATURE_PLASTIC
                | FEATURE_INDIRECT
                | FEATURE_ENVIRONMENT_MAP
                | FEATURE_PUNCTUAL,
        ),
        (
            // Fractional metallic and transmission: every lobe's weight is a rounded product.
            "principled block, partly metal, partly transmissive",
            block_of(gltf(0.8, 0.3, 0.5, 0.4), None),
            settings(outside.0, outside.1, 0.3, 4),
            FEATURE_EMITTERS | FEATURE_ENVIRONMENT | FEATURE_DIFFUSE | FEATURE_PRINCIPLED | FEATURE_INDIRECT,
        ),
    ]
}

/// The cases are checked in `PARTS` tests, so that the test harness compiles lavapipe's
/// pipelines for several of them at once.
const PARTS: usize = 4;

/// Every `PARTS`-th case from `part`: the CPU's variant against its generic code, and lavapipe's
/// specialised and generic pipelines against the CPU.
fn check_part(part: usize) {
    let g = gpu::Gpu::lavapipe().unwrap();
    for (name, c, s, bits) in cases().iter().skip(part).step_by(PARTS) {
        assert_eq!(features::analyse(c, s).bits, *bits, "{name}: feature set");
        let generic = RenderSettings { specialize: false, ..*s };
        let cpu_special = cpu::render(c, s, &no_progress).unwrap();
        let cpu_generic = cpu::render(c, &generic, &no_progress).unwrap();
        assert!(cpu_special.sum.iter().all(|p| p.is_finite()), "{name}");
        assert!(same(&cpu_special, &cpu_generic), "{name}: the CPU's variant differs from its generic code");
        let gpu_special = g.render(c, s, &no_progress).unwrap();
        let gpu_generic = g.render(c, &generic, &no_progress).unwrap();
        assert!(same(&cpu_special, &gpu_special), "{name}: lavapipe's specialised pipeline differs from the CPU");
        assert!(same(&cpu_generic, &gpu_generic), "{name}: lavapipe's generic pipeline differs from the CPU");
        if features::analyse(c, s).connect {
            // Each sample's own light subpath instead of the pool's: the same on both devices.
            let own = RenderSettings { light_pool: false, ..*s };
            let cpu_own = cpu::render(c, &own, &no_progress).unwrap();
            assert!(!same(&cpu_own, &cpu_special), "{name}: the pool changed nothing");
            assert!(
                same(&cpu_own, &g.render(c, &own, &no_progress).unwrap()),
                "{name}: without the pool, lavapipe differs"
            );
        }
    }
}

#[test]
fn variants_render_the_generic_image_part_1() {
    check_part(0);
}

#[test]
fn variants_render_the_generic_image_part_2() {
    check_part(1);
}

#[test]
fn variants_render_the_generic_image_part_3() {
    check_part(2);
}

#[test]
fn variants_render_the_generic_image_part_4() {
    check_part(3);
}

/// The cases leave out every bit between them; the scenes with light are not black, and the one
/// without is.
#[test]
fn the_cases_cover_every_feature() {
    let cases = cases();
    let covered = cases.iter().fold(0, |acc, c| acc | (FEATURES_ALL & !c.3));
    assert_eq!(covered, FEATURES_ALL, "some feature is never left out");
    let lit = |i: usize| cpu::render(&cases[i].1, &cases[i].2, &no_progress).unwrap().sum.iter().any(|p| p.x > 0.0);
    assert!((0..cases.len()).filter(|&i| i != 2 && i != 7).all(lit));
    assert!(!lit(7));
}

/// A variant that leaves out a feature the scene has renders a different image: the cases above
/// would catch a variant that ignored its bits.
#[test]
fn leaving_out_a_used_feature_changes_the_image() {
    let c = lamp_and_block(true);
    // Path tracing alone (`settings`): a set that keeps the connections but leaves out what
    // they need would run the generic code (`cpu::cpu_variant_bits`).
    let s = settings(DVec3::new(0.0, 2.5, 5.0), DVec3::new(0.0, 0.5, 0.0), 0.4, 3);
    let full = cpu::render(&c, &s, &no_progress).unwrap();
    let bits = features::analyse(&c, &s).bits;
    for bit in [FEATURE_EMITTERS, FEATURE_ENVIRONMENT, FEATURE_INDIRECT] {
        let params = c.params(&s, 0, s.spp).unwrap();
        let view = c.view(&params);
        let f = cpu::variant(bits & !bit);
        let (mut sum, mut sum_sq, mut primary) = (vec![Vec4::ZERO; 320], vec![Vec4::ZERO; 320], vec![0; 320]);
        let w = s.width as usize;
        let spans: Vec<PixelSpan> = (0..s.width).map(|x| PixelSpan { x, start: 0, count: s.spp }).collect();
        for (y, ((sum, sum_sq), primary)) in
            sum.chunks_mut(w).zip(sum_sq.chunks_mut(w)).zip(primary.chunks_mut(w)).enumerate()
        {
            f(&view, &params, y as u32, &spans, s.spp, 1, sum, sum_sq, primary);
        }
        assert_ne!(sum, full.sum, "leaving out feature bit {bit} changed nothing");
    }
}
