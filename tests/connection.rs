//! Light subpaths connected to the eye vertices (`shared::connection`): the estimator keeps the
//! image's mean (a per-pixel t-test against path tracing alone, with the power to catch a light
//! 10% brighter), lowers the noise of a room lit mostly by bounced light, and runs only where the
//! setting and the scene allow it; the CPU's pool of light subpaths keeps the mean too and
//! lowers the noise further. Its bit-identity between the CPU's variants and its generic
//! code, and its agreement with lavapipe, are in `specialisation.rs`; the lane integrator's
//! identity with the scalar one in `cli.rs`.
#[path = "common/paths.rs"]
mod paths;
use kdtrace::{
    image::metrics::two_image_test,
    kdbuild::BuildSettings,
    load,
    render::{cpu, features, Compiled, Rendered},
    settings::{Aov, Connect, RenderSettings},
};
use paths::repo;

fn no_progress(_: u64, _: u64) {}

/// The uneven-noise room (`scenes/uneven-noise.toml`): a lamp behind a partition, most walls lit
/// only after a bounce, at `width` x 3/4 of it.
fn room(light_scale: f32) -> (Compiled, RenderSettings) {
    let mut l = load(&repo("scenes/uneven-noise.toml"), BuildSettings::default()).unwrap();
    for m in &mut l.compiled.scene.materials {
        m.emission *= light_scale;
    }
    let (lo, hi) = l.compiled.world_bounds();
    let s = l.settings.resolve(lo, hi).unwrap();
    (l.compiled, RenderSettings { width: 32, height: 24, ..s })
}

fn render(c: &Compiled, s: &RenderSettings, connect: Connect, seed: u32, spp: u32) -> Rendered {
    cpu::render(c, &RenderSettings { connect, seed, spp, ..*s }, &no_progress).unwrap()
}

/// `render` with each sample's own light subpath instead of the pool (`--light-pool off`).
fn render_own(c: &Compiled, s: &RenderSettings, seed: u32, spp: u32) -> Rendered {
    render(c, &RenderSettings { light_pool: false, ..*s }, Connect::On, seed, spp)
}

#[test]
fn connections_keep_the_mean_of_path_tracing() {
    let (c, s) = room(1.0);
    // Path tracing's estimate is the heavier-tailed one (most of the room is lit by bounced
    // light): with more samples its variance estimate is trustworthy.
    let off = render(&c, &s, Connect::Off, 2, 2048);
    let (brighter, _) = room(1.1);
    let off_brighter = render(&brighter, &s, Connect::Off, 2, 2048);
    for (name, on) in [("the pool", render(&c, &s, Connect::On, 1, 256)), ("own subpaths", render_own(&c, &s, 1, 256))]
    {
        let t = two_image_test(&on.stats().unwrap(), &off.stats().unwrap(), 0.01).unwrap();
        eprintln!(
            "connections ({name}) vs path tracing: {} of {} rejected, smallest p {:.2e}",
            t.rejected, t.tests, t.min_p
        );
        assert!(t.pass, "{name}: {t:?}");
        assert!(t.tests >= 32 * 24 * 3 * 9 / 10, "{name}: too few pixels could be tested: {}", t.tests);
        // The test has power: path tracing with the lamp 10% brighter is caught.
        let t = two_image_test(&on.stats().unwrap(), &off_brighter.stats().unwrap(), 0.01).unwrap();
        assert!(!t.pass, "{name}: a 10% brighter lamp went unnoticed: {t:?}");
    }
}

/// The image's expected relative MSE from its own per-pixel variance: Σ var / n / (mean² + 0.01)
/// over pixel channels, averaged.
fn expected_rel_mse(r: &Rendered) -> f64 {
    let (mean, var) = (r.mean(), r.variance());
    let mut sum = 0.0;
    for (i, (m, v)) in mean.iter().zip(&var).enumerate() {
        for ch in 0..3 {
            let m = m[ch] as f64;
            sum += v[ch] as f64 / r.count(i) as f64 / (m * m + 0.01);
        }
    }
    sum / (mean.len() * 3) as f64
}

/// Each eye vertex picking among `pool_candidates` light vertices of the pool, by their
/// unshadowed contributions, lowers the noise against one light subpath of its own, for the
/// same shadow rays.
#[test]
fn the_pool_lowers_the_noise_of_the_connections() {
    let (c, s) = room(1.0);
    let (pool, own) = (render(&c, &s, Connect::On, 3, 64), render_own(&c, &s, 3, 64));
    let (e_pool, e_own) = (expected_rel_mse(&pool), expected_rel_mse(&own));
    eprintln!("expected relMSE at 64 spp: {e_pool:.3e} from the pool, {e_own:.3e} from own light subpaths");
    assert!(e_pool < 0.8 * e_own, "{e_pool:.3e} from the pool, {e_own:.3e} from own light subpaths");
}

#[test]
fn connections_lower_the_noise_of_bounced_light() {
    let (c, s) = room(1.0);
    let (on, off) = (render(&c, &s, Connect::On, 3, 64), render(&c, &s, Connect::Off, 3, 64));
    let (e_on, e_off) = (expected_rel_mse(&on), expected_rel_mse(&off));
    eprintln!("expected relMSE at 64 spp: {e_on:.3e} with connections, {e_off:.3e} without");
    // Measured at 256x256 against a converged reference: about a quarter.
    assert!(e_on < 0.6 * e_off, "{e_on:.3e} with connections, {e_off:.3e} without");
}

#[test]
fn the_share_is_kept_per_camera() {
    // `seen_light_share` keeps its last answer on the scene: asked again about another seed or
    // camera it must answer as a scene asked for the first time does.
    let (c, s) = room(1.0);
    let other = RenderSettings { seed: 9, ..s };
    let mut moved = s;
    moved.camera.eye.x += 0.5;
    let fresh = |s: &RenderSettings| features::seen_light_share(&room(1.0).0, s);
    let expected = [fresh(&s), fresh(&other), fresh(&moved)];
    assert!(expected[0] != expected[1] || expected[0] != expected[2], "{expected:?}: the settings change the share");
    for _ in 0..2 {
        for (s, e) in [s, other, moved].iter().zip(expected) {
            assert_eq!(features::seen_light_share(&c, s), e);
            assert_eq!(features::seen_light_share(&c, s), e, "asked twice");
        }
    }
}

#[test]
fn connections_run_where_asked_for_and_where_the_scene_allows() {
    let (c, s) = room(1.0);
    assert_eq!(s.connect, Connect::Auto, "auto by default: the scene file does not say");
    // Drawn from the pool, the connections run wherever the scene allows them.
    let pooled = features::analyse(&c, &s);
    assert!(pooled.connect && pooled.seen_light_share.is_none(), "auto with the pool connects");
    // Each sample with its own light subpath (`--light-pool off`): the lamp is behind a
    // partition, and most of what the camera sees is lit after a bounce.
    let f = features::analyse(&c, &RenderSettings { light_pool: false, ..s });
    let share = f.seen_light_share.expect("auto decides");
    assert!(share < features::AUTO_CONNECT_BELOW, "{share}");
    assert!(f.connect, "on by default in this room, {share} of the first hits seeing the lamp");
    let s = RenderSettings { connect: Connect::On, ..s };
    assert!(features::analyse(&c, &s).connect, "on where asked for, in a room of Lambertian walls");
    assert!(c.params(&s, 0, 1).unwrap().connect == 1);
    for (why, s) in [
        ("switched off", RenderSettings { connect: Connect::Off, ..s }),
        ("direct light only", RenderSettings { max_bounces: 0, ..s }),
        ("an albedo image", RenderSettings { aov: Aov::Albedo, ..s }),
    ] {
        assert!(!features::analyse(&c, &s).connect, "{why}");
        assert_eq!(c.params(&s, 0, 1).unwrap().connect, 0, "{why}");
    }
    // A glossy wall: the connection's vertices would need its BSDF, so the scene does without.
    let mut glossy = room(1.0).0;
    for m in glossy.scene.materials.iter_mut().filter(|m| m.emission.truncate() == shared::glam::Vec3::ZERO) {
        m.kind = shared::layout::MATERIAL_CONDUCTOR;
    }
    assert!(!features::analyse(&glossy, &s).connect);
    assert_eq!(glossy.params(&s, 0, 1).unwrap().connect, 0);
}
