//! Short-stack traversal with restart returns exactly the brute-force hit for every stack size,
//! restarts when the stack is small, and never restarts when it is as deep as the tree.
#[path = "common/paths.rs"]
mod paths;
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
use shared::{
    glam::Vec3,
    kdtree::{intersect, intersect_brute_force, occluded},
    layout::KD_MAX_DEPTH,
    short_stack::{intersect_short, occluded_short, ShortHit},
};

fn rays(c: &Compiled, n: usize, seed: u64) -> Vec<(Vec3, Vec3)> {
    let mut rng = Pcg64::seed_from_u64(seed);
    let (lo, hi) = (c.tree().bounds_min, c.tree().bounds_max);
    (0..n)
        .map(|_| {
            let o = lo
                + (hi - lo)
                    * Vec3::new(rng.random_range(-0.2..1.2), rng.random_range(-0.2..1.2), rng.random_range(-0.2..1.2));
            let t = &c.scene.triangles[rng.random_range(0..c.scene.triangles.len())];
            let target = Vec3::new(t.v0.x, t.v0.y, t.v0.z) * 0.4
                + Vec3::new(t.v1.x, t.v1.y, t.v1.z) * 0.3
                + Vec3::new(t.v2.x, t.v2.y, t.v2.z) * 0.3;
            (o, target - o)
        })
        .collect()
}

/// (hits, restarts) over all rays; panics on the first ray whose hit differs from brute force.
fn check<const S: usize>(c: &Compiled, rays: &[(Vec3, Vec3)], what: &str) -> (usize, u64) {
    let params = c.bounds_params();
    let scene = c.view(&params);
    rays.par_iter()
        .map(|&(o, d)| {
            let ShortHit { hit, restarts } = intersect_short::<S>(&scene, o, d, f32::MAX);
            let brute = intersect_brute_force(&scene, o, d, f32::MAX);
            assert_eq!(
                hit.t.to_bits(),
                brute.t.to_bits(),
                "{what}, stack {S}: o={o:?} d={d:?}: short {} (tri {}) brute {} (tri {})",
                hit.t,
                hit.triangle,
                brute.t,
                brute.triangle
            );
            assert_eq!(
                occluded_short::<S>(&scene, o, d, f32::MAX).hit.is_hit(),
                brute.is_hit(),
                "{what}, stack {S}: occlusion differs for o={o:?} d={d:?}"
            );
            // With the full stack both traversals do identical work.
            let full = intersect(&scene, o, d, f32::MAX);
            if S > KD_MAX_DEPTH as usize {
                assert_eq!((restarts, hit.nodes, hit.tests), (0, full.nodes, full.tests));
                assert_eq!(occluded(&scene, o, d, f32::MAX), brute.is_hit());
            }
            (brute.is_hit() as usize, restarts as u64)
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
}

fn all_sizes(c: &Compiled, rays: &[(Vec3, Vec3)], what: &str, min_hits: usize) {
    let r1 = check::<1>(c, rays, what);
    let r2 = check::<2>(c, rays, what);
    let r4 = check::<4>(c, rays, what);
    let r8 = check::<8>(c, rays, what);
    let full = check::<{ KD_MAX_DEPTH as usize + 1 }>(c, rays, what);
    eprintln!(
        "{what}: {} rays, {} hits; restarts with stack 1/2/4/8/full: {}/{}/{}/{}/{}",
        rays.len(),
        r1.0,
        r1.1,
        r2.1,
        r4.1,
        r8.1,
        full.1
    );
    assert!(r1.1 > r4.1 && r4.1 >= r8.1, "{what}: smaller stacks must restart more");
    assert!(r1.1 > 0, "{what}: a one-entry stack never restarted: the restart path went untested");
    assert!(r1.0 >= min_hits, "{what}: only {} hits", r1.0);
}

#[test]
fn short_stack_matches_brute_force_on_the_bunny() {
    let c =
        compile(obj::load_obj(&mesh("bunny-stanford-bun_zipper/bun_zipper.obj")).unwrap(), BuildSettings::default());
    all_sizes(&c, &rays(&c, 20_000, 5), "bunny", 15_000);
}

#[test]
fn short_stack_matches_brute_force_on_the_staircase_grid() {
    let c = compile(procedural::staircase(16, 8).unwrap(), BuildSettings::default());
    let mut r = Vec::new();
    for x in -1..=18 {
        for y in -1..=18 {
            for z in -1..=9 {
                let o = Vec3::new(x as f32, y as f32, z as f32);
                for d in [
                    Vec3::X,
                    -Vec3::Y,
                    Vec3::Z,
                    Vec3::new(1.0, 1.0, 0.0),
                    Vec3::new(-1.0, 0.0, 1.0),
                    Vec3::new(1.0, -1.0, -1.0),
                ] {
                    r.push((o, d));
                    r.push((o + Vec3::splat(0.5), d));
                }
            }
        }
    }
    all_sizes(&c, &r, "staircase", r.len() / 4);
}
