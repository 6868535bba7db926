//! The CPU's eight-wide BVH must return what testing every triangle returns: the same distance,
//! triangle (the lowest id where coincident faces tie) and barycentrics bit for bit, and any-hit
//! queries must agree with it, for unbounded and for short rays. Packets of sixteen rays
//! (`wide_packet`) must give every ray the same answer, in packets of unrelated rays and in
//! packets of neighbouring ones.
#[path = "common/paths.rs"]
mod paths;
#[path = "common/rays.rs"]
mod rays;
use kdtrace::{
    compile,
    kdbuild::BuildSettings,
    render::Compiled,
    scene::{obj, procedural},
};
use paths::mesh;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;
use rays::{grid_line_rays, random_point_on, random_unit};
use shared::{
    glam::Vec3,
    kdtree::{intersect_brute_force, Hit},
    layout::WIDE_MAX_DEPTH as MAX_DEPTH,
    wide_bvh,
    wide_packet::{self, PACKET},
};

/// The scene with its wide BVH.
fn view(c: &Compiled) -> shared::scene::SceneView<'_> {
    c.wide_bvh();
    c.view(&c.bounds_params())
}

/// Compares the wide BVH with brute force (and the k-d tree) on every ray, each with its own
/// t_max; returns (rays, hits). Panics on the first mismatch.
fn check_rays(c: &Compiled, rays: &[(Vec3, Vec3, f32)]) -> (usize, usize) {
    let scene = view(c);
    let hits = rays
        .par_iter()
        .map(|&(o, d, t_max)| {
            let wide = wide_bvh::traverse(&scene, o, d, t_max, false);
            let brute = intersect_brute_force(&scene, o, d, t_max);
            assert_eq!(
                wide.t.to_bits(),
                brute.t.to_bits(),
                "ray o={o:?} d={d:?} t_max={t_max}: wide t={} (tri {}) brute t={} (tri {})",
                wide.t,
                wide.triangle,
                brute.t,
                brute.triangle
            );
            // Of triangles hit at the same distance (coincident faces), the lowest id, as brute
            // force picks.
            assert_eq!(wide.triangle, brute.triangle, "ray o={o:?} d={d:?}: another triangle at the same t");
            assert_eq!([wide.u, wide.v, wide.w].map(f32::to_bits), [brute.u, brute.v, brute.w].map(f32::to_bits));
            let any = wide_bvh::traverse(&scene, o, d, t_max, true);
            assert_eq!(any.is_hit(), brute.is_hit(), "any hit disagrees for o={o:?} d={d:?} t_max={t_max}");
            if any.is_hit() {
                assert!(any.t < t_max && any.t > 0.0);
            }
            brute.is_hit() as usize
        })
        .sum::<usize>();
    check_packets(&scene, rays);
    // Neighbouring rays in a packet: ordered by direction octant, then origin.
    let mut sorted = rays.to_vec();
    let octant = |d: Vec3| (d.x < 0.0) as u32 | ((d.y < 0.0) as u32) << 1 | ((d.z < 0.0) as u32) << 2;
    sorted.sort_by(|a, b| octant(a.1).cmp(&octant(b.1)).then(a.0.x.total_cmp(&b.0.x)));
    check_packets(&scene, &sorted);
    (rays.len(), hits)
}

/// Casts `rays` in packets of `PACKET` (the last one short) and compares every ray's closest
/// and any hit with the single-ray traversal's, which `check_rays` compares with brute force.
fn check_packets(scene: &shared::scene::SceneView, rays: &[(Vec3, Vec3, f32)]) {
    rays.par_chunks(PACKET).for_each(|chunk| {
        let mut origin = [Vec3::ZERO; PACKET];
        let mut dir = [Vec3::Z; PACKET];
        let mut t_max = [0.0; PACKET];
        for (i, &(o, d, t)) in chunk.iter().enumerate() {
            (origin[i], dir[i], t_max[i]) = (o, d, t);
        }
        let closest = wide_packet::traverse(scene, &origin, &dir, &t_max, chunk.len(), false);
        let any = wide_packet::traverse(scene, &origin, &dir, &t_max, chunk.len(), true);
        for (i, &(o, d, t)) in chunk.iter().enumerate() {
            let single = wide_bvh::traverse(scene, o, d, t, false);
            let bits = |h: &Hit| [h.t, h.u, h.v, h.w].map(f32::to_bits);
            assert_eq!(
                (bits(&closest[i]), closest[i].triangle),
                (bits(&single), single.triangle),
                "packet ray {i} o={o:?} d={d:?} t_max={t}: packet t={} (tri {}) single t={} (tri {})",
                closest[i].t,
                closest[i].triangle,
                single.t,
                single.triangle
            );
            assert_eq!(any[i].is_hit(), single.is_hit(), "packet any hit disagrees for o={o:?} d={d:?} t_max={t}");
            if any[i].is_hit() {
                assert!(any[i].t < t && any[i].t > 0.0);
            }
        }
    });
}

/// A third of the rays start anywhere in the (enlarged) box in random directions; a third are
/// aimed from outside at random points of random triangles; a third start on a random triangle
/// (as a bounce does) and run a random short length.
fn random_rays(c: &Compiled, n: usize, seed: u64) -> Vec<(Vec3, Vec3, f32)> {
    let mut rng = Pcg64::seed_from_u64(seed);
    let (lo, hi) = (c.tree().bounds_min, c.tree().bounds_max);
    let center = 0.5 * (lo + hi);
    let radius = 0.5 * (hi - lo).length();
    (0..n)
        .map(|i| {
            let t = &c.scene.triangles[rng.random_range(0..c.scene.triangles.len())];
            let on = random_point_on(t, &mut rng);
            match i % 3 {
                0 => {
                    let u = Vec3::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                    );
                    (center + (hi - lo) * 0.6 * u, random_unit(&mut rng), f32::MAX)
                }
                1 => {
                    let o = center + random_unit(&mut rng) * (2.0 * radius);
                    (o, on - o, f32::MAX)
                }
                _ => (on, random_unit(&mut rng), rng.random_range(0.0..0.2) * radius),
            }
        })
        .collect()
}

fn mesh_case(rel: &str, seed: u64) {
    let c = compile(obj::load_obj(&mesh(rel)).unwrap(), BuildSettings::default());
    assert!(c.wide_bvh().depth() <= MAX_DEPTH);
    let (rays, hits) = check_rays(&c, &random_rays(&c, 100_000, seed));
    assert!(hits > rays / 3, "{rel}: only {hits} of {rays} rays hit: the test would prove little");
    eprintln!(
        "{rel}: {} triangles, {} references, {} wide nodes, depth {}, {rays} rays, {hits} hits, all equal to brute force",
        c.scene.triangles.len(),
        c.wide_bvh().references,
        c.wide_bvh().nodes.len(),
        c.wide_bvh().depth()
    );
}

#[test]
fn bunny_matches_brute_force() {
    mesh_case("bunny-stanford-bun_zipper/bun_zipper.obj", 1);
}

#[test]
fn dragon_matches_brute_force() {
    mesh_case("dragon-23k/dragon.obj", 2);
}

#[test]
fn cornell_box_original_matches_brute_force() {
    mesh_case("CornellBox-Original/CornellBox-Original.obj", 3);
}

/// A room of long, thin wall strips, tilted a little off the axes, around a cloud of small
/// triangles: spatial splits cut the strips, so a triangle sits in several leaves, each with the
/// box of its part only. No ray may slip between the parts, find a triangle twice to a different
/// answer, or lose a tie.
#[test]
fn a_room_cut_by_spatial_splits_matches_brute_force() {
    use kdtrace::scene::{diffuse, Scene};
    use shared::layout::Triangle;
    let mut rng = Pcg64::seed_from_u64(11);
    let tilt = |p: Vec3| Vec3::new(p.x + 0.013 * p.y, p.y + 0.007 * p.z, p.z + 0.011 * p.x);
    let tri = |a: Vec3, b: Vec3, c: Vec3| Triangle {
        v0: tilt(a).extend(0.0),
        v1: tilt(b).extend(0.0),
        v2: tilt(c).extend(0.0),
    };
    let mut tris = Vec::new();
    for k in 0..24 {
        let (z0, z1) = (k as f32 / 24.0 * 10.0, (k + 1) as f32 / 24.0 * 10.0);
        for y in [0.0, 10.0] {
            tris.push(tri(Vec3::new(0.0, y, z0), Vec3::new(10.0, y, z0), Vec3::new(10.0, y, z1)));
            tris.push(tri(Vec3::new(0.0, y, z0), Vec3::new(10.0, y, z1), Vec3::new(0.0, y, z1)));
        }
        for x in [0.0, 10.0] {
            tris.push(tri(Vec3::new(x, 0.0, z0), Vec3::new(x, 10.0, z0), Vec3::new(x, 10.0, z1)));
            tris.push(tri(Vec3::new(x, 0.0, z0), Vec3::new(x, 10.0, z1), Vec3::new(x, 0.0, z1)));
        }
    }
    for _ in 0..3000 {
        let p = Vec3::new(rng.random_range(1.0..9.0), rng.random_range(1.0..9.0), rng.random_range(1.0..9.0));
        tris.push(tri(p, p + random_unit(&mut rng) * 0.2, p + random_unit(&mut rng) * 0.2));
    }
    let n = tris.len();
    let scene = Scene::new(tris, vec![0; n], vec![diffuse(Vec3::splat(0.5), Vec3::ZERO)], vec!["m".into()]).unwrap();
    let c = compile(scene, BuildSettings::default());
    let references = c.wide_bvh().references;
    assert!(references > n + n / 50, "{references} references for {n} triangles: the walls were hardly cut");
    let (rays, hits) = check_rays(&c, &random_rays(&c, 100_000, 12));
    assert!(hits > rays / 2, "only {hits} of {rays} rays hit");
    eprintln!("room: {n} triangles, {references} references, {rays} rays equal to brute force");
}

/// Rays along grid lines of a grid-aligned staircase: axis-parallel, through vertices, along
/// edges, lying in faces and in box planes.
#[test]
fn staircase_grid_line_rays_match_brute_force() {
    let (steps, width) = (16u32, 8u32);
    let c = compile(procedural::staircase(steps, width).unwrap(), BuildSettings::default());
    // Each twice: unbounded, and one unit long.
    let rays: Vec<(Vec3, Vec3, f32)> =
        grid_line_rays(steps, width).into_iter().flat_map(|(o, d)| [(o, d, f32::MAX), (o, d, 1.0)]).collect();
    let (count, hits) = check_rays(&c, &rays);
    assert!(hits > count / 8, "only {hits} of {count} grid rays hit");
}

#[test]
fn garbage_rays_miss_without_hanging() {
    let c = compile(procedural::staircase(4, 2).unwrap(), BuildSettings::default());
    let scene = view(&c);
    let (nan, inf) = (f32::NAN, f32::INFINITY);
    for (o, d) in [
        (Vec3::new(nan, 1.0, 1.0), Vec3::X),
        (Vec3::new(1.0, 1.0, 1.0), Vec3::new(nan, 0.0, 0.0)),
        (Vec3::new(inf, 1.0, 1.0), -Vec3::X),
        (Vec3::new(1.0, 1.0, 1.0), Vec3::new(inf, 1.0, 0.0)),
        (Vec3::new(1.0, 1.0, 1.0), Vec3::ZERO),
        (Vec3::new(1.0, 1.0, 1.0), Vec3::new(1e-40, 0.0, 0.0)),
    ] {
        assert!(!wide_bvh::traverse(&scene, o, d, f32::MAX, false).is_hit(), "o={o:?} d={d:?}");
        // The same ray in a packet beside one that hits.
        let mut origin = [Vec3::new(1.0, 1.0, 1.0); PACKET];
        let mut dir = [Vec3::new(0.3, -1.0, 0.2); PACKET];
        (origin[3], dir[3]) = (o, d);
        let hits = wide_packet::traverse(&scene, &origin, &dir, &[f32::MAX; PACKET], PACKET, false);
        assert!(!hits[3].is_hit(), "in a packet: o={o:?} d={d:?}");
        assert_eq!(hits[0].triangle, wide_bvh::traverse(&scene, origin[0], dir[0], f32::MAX, false).triangle);
    }
}
