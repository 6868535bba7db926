//! Scene analysis: what a loaded scene with its render settings uses (`shared::features`), for
//! `render --json` (`features`) and for choosing the specialised variant of the integrator that
//! both renderers run (`RenderSettings::specialize`; off, the generic code).
use crate::render::Compiled;
use crate::scene::Scene;
use crate::settings::{Aov, Connect, RenderSettings};
use serde::Serialize;
use shared::features::{
    connection_applies, FEATURES_ALL, FEATURE_ALPHA_MASKS, FEATURE_CONDUCTOR, FEATURE_CONNECT, FEATURE_DIELECTRIC,
    FEATURE_DIFFUSE, FEATURE_EMITTERS, FEATURE_ENVIRONMENT, FEATURE_ENVIRONMENT_MAP, FEATURE_INDIRECT,
    FEATURE_MANY_EMITTERS, FEATURE_PLASTIC, FEATURE_PRINCIPLED, FEATURE_PUNCTUAL, FEATURE_TEXTURES,
    FEATURE_VERTEX_NORMALS,
};
use shared::layout::{
    Material, MATERIAL_CONDUCTOR, MATERIAL_DIELECTRIC, MATERIAL_DIFFUSE, MATERIAL_PLASTIC, MATERIAL_PRINCIPLED,
    NO_TEXTURE, TEXTURE_ALBEDO, TEXTURE_ALPHA,
};
use shared::vecmath::{max_component, xyz};

/// The feature set and the facts behind it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Features {
    /// `shared::features` bits.
    pub bits: u32,
    /// Emitting triangles.
    pub emitters: usize,
    /// Their total power, Σ area × luminance of the emitted radiance (scene units).
    pub emitter_power: f64,
    /// "black" or "constant".
    pub environment: &'static str,
    /// Material kinds present.
    pub materials: Vec<&'static str>,
    /// Whether materials that triangles use have textures, and alpha masks among them.
    pub textures: bool,
    pub alpha_masks: bool,
    /// Whether some triangle has vertex normals.
    pub vertex_normals: bool,
    /// Indirect bounces allowed.
    pub bounces: u32,
    /// Whether light can reach the camera after a bounce.
    pub indirect: bool,
    /// Whether light subpaths connect to the eye vertices (`shared::connection`): asked for,
    /// and the scene allows it.
    pub connect: bool,
    /// With `--connect auto` where the scene allows the connections: the share of the camera's
    /// first hits that see the light they sample (`seen_light_share`), which decided.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seen_light_share: Option<f64>,
    /// The integrator variant that renders it: "generic", or "specialised" for `bits`.
    pub variant: &'static str,
    /// The feature bits of that variant (`FEATURES_ALL` for the generic code).
    pub variant_bits: u32,
    /// Whether the CPU ran it sixteen samples at a time (`shared::lanes`).
    pub lanes: bool,
    /// Whether the connections draw their light subpaths from the pool shared by all pixels
    /// (`shared::connection::LightPool`): they run and the settings ask for it
    /// (`RenderSettings::light_pool`). `RenderParams::light_pool` is this.
    pub light_pool: bool,
}

/// Each bit's name, as `render --json` and the tests print them.
pub const FEATURE_NAMES: [(u32, &str); 15] = [
    (FEATURE_EMITTERS, "emitters"),
    (FEATURE_MANY_EMITTERS, "many_emitters"),
    (FEATURE_ENVIRONMENT, "environment"),
    (FEATURE_DIFFUSE, "diffuse"),
    (FEATURE_INDIRECT, "indirect"),
    (FEATURE_CONDUCTOR, "conductor"),
    (FEATURE_DIELECTRIC, "dielectric"),
    (FEATURE_PLASTIC, "plastic"),
    (FEATURE_PRINCIPLED, "principled"),
    (FEATURE_TEXTURES, "textures"),
    (FEATURE_ALPHA_MASKS, "alpha_masks"),
    (FEATURE_VERTEX_NORMALS, "vertex_normals"),
    (FEATURE_ENVIRONMENT_MAP, "environment_map"),
    (FEATURE_PUNCTUAL, "punctual_lights"),
    (FEATURE_CONNECT, "connect"),
];

/// The materials that triangles use (a scene file may define more).
fn used_materials(scene: &Scene) -> Vec<&Material> {
    let mut used = vec![false; scene.materials.len()];
    for t in &scene.info {
        used[t.material as usize] = true;
    }
    scene.materials.iter().zip(&used).filter(|(_, &u)| u).map(|(m, _)| m).collect()
}

/// Whether a material that triangles use has an alpha mask.
pub fn uses_alpha_masks(scene: &Scene) -> bool {
    used_materials(scene).iter().any(|m| m.textures[TEXTURE_ALPHA] != NO_TEXTURE)
}

/// The feature bits of the variant that renders `c` with `s`: the scene's set, or every bit for
/// the generic code.
pub fn variant_bits(c: &Compiled, s: &RenderSettings) -> u32 {
    if s.specialize {
        analyse(c, s).bits
    } else {
        FEATURES_ALL
    }
}

/// `Connect::Auto`, where each sample traces its own light subpath (`RenderSettings::light_pool`
/// off), connects where fewer of the camera's first hits than this
/// see the point they sample on a light (`seen_light_share`). In the time-against-error
/// benchmark those connections paid well where the light mostly arrives after a bounce (a room
/// lit around a partition, Sponza's arcades) and cost about as much as they saved where most
/// of what the camera sees is lit directly (the Cornell boxes); BENCHMARKS.md gives each
/// scene's share and times. Drawn from the pool, the connections paid on every scene of
/// the benchmark, so `auto` connects wherever the scene allows it.
pub const AUTO_CONNECT_BELOW: f64 = 0.5;

/// Camera rays through a grid of pixel centres per axis for `seen_light_share`.
const SEEN_LIGHT_GRID: u32 = 32;

/// The share of the camera's first hits (one through the centre of each cell of a
/// `SEEN_LIGHT_GRID`² grid over the image) that see a point sampled on an emitting triangle, as
/// next-event estimation samples it, among those that face one; 1 where none does. Two rays a
/// cell, through the render's own traversal: small beside any render.
pub fn seen_light_share(c: &Compiled, s: &RenderSettings) -> f64 {
    use shared::layout::TRAVERSAL_WIDE_BVH;
    use shared::rng::{pcg4d, u32_to_unit_f32};
    let Ok(mut params) = c.params(&RenderSettings { connect: Connect::Off, ..*s }, 0, 1) else {
        return 1.0;
    };
    // The share depends on the camera, the image size and the seed, which the parameters as
    // they stand here hold. (The structures agree but on a ray that grazes a triangle it starts
    // within rounding distance of (README, `--traversal`); kept, one render's decision stays
    // the same whichever structure is built by the time it asks again.)
    let mut cache = c.seen_light.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((key, share)) = *cache {
        if key == params {
            return share;
        }
    }
    let key = params;
    // The wide BVH where it is built or the render asks for it (without the lanes' split, which
    // only they need), else the k-d tree.
    if c.wide.get().is_some() || params.traversal == TRAVERSAL_WIDE_BVH {
        c.wide_bvh();
        params.traversal = TRAVERSAL_WIDE_BVH;
    }
    let view = c.view(&params);
    let (mut facing, mut seen) = (0u32, 0u32);
    for j in 0..SEEN_LIGHT_GRID {
        for i in 0..SEEN_LIGHT_GRID {
            let x = (i as f32 + 0.5) * s.width as f32 / SEEN_LIGHT_GRID as f32;
            let y = (j as f32 + 0.5) * s.height as f32 / SEEN_LIGHT_GRID as f32;
            let [u0, u1, ..] = pcg4d(i, j, s.seed, 0x5ee1_1647).map(u32_to_unit_f32);
            if let Some(sees) = shared::connection::first_hit_sees_light(&view, &params, x, y, u0, u1) {
                facing += 1;
                seen += u32::from(sees);
            }
        }
    }
    let share = if facing == 0 { 1.0 } else { seen as f64 / facing as f64 };
    *cache = Some((key, share));
    share
}

/// What the command line and the web UI say of a scene that [`lit`] finds unlit.
pub const UNLIT: &str = "nothing emits light (no emitting material, light or environment): the image is black";

/// Whether anything lights the scene under settings `s`: an emitting triangle, a punctual
/// light, an environment map or a constant environment that is not black. Without any, every
/// radiance pixel is zero, which the command line and the web UI warn of ([`UNLIT`]).
pub fn lit(c: &Compiled, s: &RenderSettings) -> bool {
    let scene = &c.scene;
    !scene.lights.is_empty()
        || !scene.punctual_lights.is_empty()
        || scene.environment_map.is_some()
        || max_component(s.environment) > 0.0
}

pub fn analyse(c: &Compiled, s: &RenderSettings) -> Features {
    let scene = &c.scene;
    let emitters = scene.lights.len();
    // `+ 0.0`: an empty float sum is −0.0.
    let emitter_power = 0.0
        + scene
            .lights
            .iter()
            .map(|l| {
                let m = &scene.materials[scene.info[l.triangle as usize].material as usize];
                l.area as f64 * shared::vecmath::luminance(xyz(m.emission)) as f64
            })
            .sum::<f64>();
    let map = scene.environment_map.is_some();
    let punctual = !scene.punctual_lights.is_empty();
    // The map replaces the constant colour.
    let environment = !map && max_component(s.environment) > 0.0;
    let used = used_materials(scene);
    let diffuse = used.iter().any(|m| m.kind == MATERIAL_DIFFUSE);
    let conductor = used.iter().any(|m| m.kind == MATERIAL_CONDUCTOR);
    let dielectric = used.iter().any(|m| m.kind == MATERIAL_DIELECTRIC);
    let plastic = used.iter().any(|m| m.kind == MATERIAL_PLASTIC);
    let principled = used.iter().any(|m| m.kind == MATERIAL_PRINCIPLED);
    // A conductor always reflects (its Fresnel reflectance is positive at every angle), and a
    // dielectric reflects or lets light through.
    // A plastic's coating and a principled material's specular lobe reflect too.
    let reflects = conductor
        || dielectric
        || plastic
        || principled
        || used.iter().any(|m| {
            m.kind == MATERIAL_DIFFUSE
                && (max_component(xyz(m.albedo)) > 0.0 || m.textures[TEXTURE_ALBEDO] != NO_TEXTURE)
        });
    // Texture maps other than the alpha mask change materials at hits; a mask changes what a ray
    // hits.
    let textures =
        used.iter().any(|m| m.textures.iter().enumerate().any(|(slot, &t)| slot != TEXTURE_ALPHA && t != NO_TEXTURE));
    let alpha_masks = uses_alpha_masks(scene);
    // A normal map bends the shading normal as vertex normals do (`surface::shading_normal`).
    let vertex_normals = (!scene.attributes.is_empty()
        && used.iter().any(|m| m.textures[shared::layout::TEXTURE_NORMAL] != NO_TEXTURE))
        || scene.attributes.iter().any(|a| [a.n0, a.n1, a.n2].iter().any(|n| n.truncate() != shared::glam::Vec3::ZERO));
    // (Every emissive triangle is in the light table: `emitters` counts them all.) A render
    // without indirect bounces still follows the BSDF sample to an emitter (MIS), so the bounce
    // limit does not enter.
    let indirect = (emitters > 0 || environment || map || punctual) && reflects;
    let mut bits = 0;
    for (on, bit) in [
        (emitters > 0, FEATURE_EMITTERS),
        (c.light_count > 1, FEATURE_MANY_EMITTERS),
        (environment, FEATURE_ENVIRONMENT),
        (diffuse, FEATURE_DIFFUSE),
        (indirect, FEATURE_INDIRECT),
        (conductor, FEATURE_CONDUCTOR),
        (dielectric, FEATURE_DIELECTRIC),
        (plastic, FEATURE_PLASTIC),
        (principled, FEATURE_PRINCIPLED),
        (textures, FEATURE_TEXTURES),
        (alpha_masks, FEATURE_ALPHA_MASKS),
        (vertex_normals, FEATURE_VERTEX_NORMALS),
        (map, FEATURE_ENVIRONMENT_MAP),
        (punctual, FEATURE_PUNCTUAL),
    ] {
        if on {
            bits |= bit;
        }
    }
    // A setting, not a fact of the scene: on where asked for and the scene's other bits allow
    // it, for the radiance image with a bounce to connect; by default (`Connect::Auto`) wherever
    // the connections draw from the pool, and otherwise only where the camera's first
    // hits mostly do not see the light.
    let allowed = s.aov == Aov::Radiance && s.max_bounces > 0 && connection_applies(bits);
    let seen_light = (allowed && s.connect == Connect::Auto && !s.light_pool).then(|| seen_light_share(c, s));
    let connect = allowed
        && match s.connect {
            Connect::On => true,
            Connect::Off => false,
            Connect::Auto => s.light_pool || seen_light.is_some_and(|share| share < AUTO_CONNECT_BELOW),
        };
    if connect {
        bits |= FEATURE_CONNECT;
    }
    Features {
        bits,
        emitters,
        emitter_power,
        environment: if map {
            "map"
        } else if environment {
            "constant"
        } else {
            "black"
        },
        materials: [
            (diffuse, "diffuse"),
            (conductor, "conductor"),
            (dielectric, "dielectric"),
            (plastic, "plastic"),
            (principled, "principled"),
        ]
        .iter()
        .filter(|m| m.0)
        .map(|m| m.1)
        .collect(),
        textures: textures || alpha_masks,
        alpha_masks,
        vertex_normals,
        bounces: s.max_bounces,
        indirect,
        connect,
        seen_light_share: seen_light,
        variant: if s.specialize { "specialised" } else { "generic" },
        variant_bits: if s.specialize { bits } else { FEATURES_ALL },
        lanes: false,
        light_pool: connect && s.light_pool,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::procedural::{emitter, furnace};
    use crate::settings::camera::Camera;
    use shared::features::FEATURES_ALL;
    use shared::glam::{DVec3, Vec3};

    fn settings(bounces: u32, environment: Vec3) -> RenderSettings {
        let camera = Camera { eye: DVec3::new(0.0, 0.0, 5.0), target: DVec3::ZERO, up: DVec3::Y, fov_deg: 30.0 };
        RenderSettings { max_bounces: bounces, environment, ..RenderSettings::with_camera(camera) }
    }

    #[test]
    fn auto_connects_where_the_first_hits_do_not_see_the_light() {
        let c = crate::compile(furnace(0.5, 1.0).unwrap(), Default::default());
        let inside = |eye: DVec3, target: DVec3| RenderSettings {
            max_bounces: 3,
            ..RenderSettings::with_camera(Camera { eye, target, up: DVec3::Y, fov_deg: 60.0 })
        };
        // Inside the furnace every first hit sees the walls it samples (a sample on its own
        // wall faces it edge-on and is not counted).
        let s = inside(DVec3::new(0.0, 0.0, 0.5), DVec3::new(0.0, 0.0, -1.0));
        assert_eq!(seen_light_share(&c, &s), 1.0);
        // Drawn from the pool, the connections run wherever the scene allows them; each sample
        // with its own light subpath (`--light-pool off`), they do not run here.
        let pooled = analyse(&c, &s);
        assert!(pooled.connect && pooled.bits & FEATURE_CONNECT != 0 && pooled.seen_light_share.is_none());
        let s = RenderSettings { light_pool: false, ..s };
        let own = analyse(&c, &s);
        assert!(!own.connect && own.bits & FEATURE_CONNECT == 0);
        assert_eq!(own.seen_light_share, Some(1.0));
        // `on` runs them all the same.
        let on = analyse(&c, &RenderSettings { connect: Connect::On, ..s });
        assert!(on.connect && on.bits & FEATURE_CONNECT != 0);
        // Scenes whose light the camera's first hits mostly do not see: `tests/connection.rs`
        // (a room lit from behind a partition); and one that does: `tests/cli.rs` (the Cornell box).
    }

    #[test]
    fn the_set_says_what_the_scene_uses() {
        // A box that emits and reflects everywhere: many emitters, indirect light.
        let c = crate::compile(furnace(0.5, 1.0).unwrap(), Default::default());
        let f = analyse(&c, &settings(3, Vec3::ZERO));
        // Lambertian walls lit by emitting triangles allow the connections: `off` and `on` say
        // whether they run, `auto` (the default) decides from what the camera sees.
        let off = analyse(&c, &RenderSettings { connect: Connect::Off, ..settings(3, Vec3::ZERO) });
        assert_eq!(off.bits, FEATURE_EMITTERS | FEATURE_MANY_EMITTERS | FEATURE_DIFFUSE | FEATURE_INDIRECT);
        assert_eq!((off.connect, off.seen_light_share), (false, None));
        let on = analyse(&c, &RenderSettings { connect: Connect::On, ..settings(3, Vec3::ZERO) });
        assert_eq!((on.bits, on.connect, on.seen_light_share), (off.bits | FEATURE_CONNECT, true, None));
        assert_eq!((f.bits, f.connect, f.seen_light_share), (on.bits, true, None), "auto, with the pool");
        let own = analyse(&c, &RenderSettings { light_pool: false, ..settings(3, Vec3::ZERO) });
        let share = own.seen_light_share.unwrap();
        assert_eq!(own.connect, share < AUTO_CONNECT_BELOW, "{share}");
        assert_eq!(own.bits, if own.connect { on.bits } else { off.bits });
        assert_eq!(f.emitters, 12);
        // Six faces of area 4, emission 1 (luminance 1).
        assert!((f.emitter_power - 24.0).abs() < 1e-4, "{}", f.emitter_power);
        // Black surfaces: nothing is reflected.
        let c = crate::compile(furnace(0.0, 1.0).unwrap(), Default::default());
        assert_eq!(analyse(&c, &settings(3, Vec3::ZERO)).bits & FEATURE_INDIRECT, 0);
        // An emitting quad under a grey sky.
        let c = crate::compile(emitter(Vec3::ONE, true).unwrap(), Default::default());
        let f = analyse(&c, &settings(4, Vec3::splat(0.2)));
        assert_eq!(f.environment, "constant");
        assert_ne!(f.bits & FEATURE_ENVIRONMENT, 0);
        assert_eq!(f.emitters, 2);
        assert_eq!(f.variant, "specialised");
        assert_eq!(f.variant_bits, f.bits);
        assert_eq!(f.bits & !FEATURES_ALL, 0);
        let generic = analyse(&c, &RenderSettings { specialize: false, ..settings(4, Vec3::ZERO) });
        assert_eq!((generic.variant, generic.variant_bits), ("generic", FEATURES_ALL));
        // Without the sky only the emitters light it.
        assert_eq!(generic.bits & FEATURE_ENVIRONMENT, 0);
    }
}
