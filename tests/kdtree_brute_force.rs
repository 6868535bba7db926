//! The k-d traversal must return exactly what testing every triangle returns: the same distance
//! bit for bit and the same triangle, unless two triangles are hit at that very distance.
#[path = "common/paths.rs"]
mod paths;
#[path = "common/rays.rs"]
mod rays;
use kdtrace::{
    compile,
    kdbuild::{validate, BuildSettings},
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
    kdtree::{intersect, intersect_brute_force, occluded},
    scene::SceneView,
    triangle::RayShear,
};

fn view(c: &Compiled) -> SceneView<'_> {
    c.view(&c.bounds_params())
}

/// Compares tree and brute force on every ray; returns (rays, hits). Panics on the first mismatch.
fn check_rays(c: &Compiled, rays: &[(Vec3, Vec3)]) -> (usize, usize) {
    let scene = view(c);
    let hits: usize = rays
        .par_iter()
        .map(|&(o, d)| {
            let tree = intersect(&scene, o, d, f32::MAX);
            let brute = intersect_brute_force(&scene, o, d, f32::MAX);
            assert_eq!(
                tree.t.to_bits(),
                brute.t.to_bits(),
                "ray o={o:?} d={d:?}: tree t={} (tri {}) brute t={} (tri {})",
                tree.t,
                tree.triangle,
                brute.t,
                brute.triangle
            );
            if tree.triangle != brute.triangle {
                // A tie: the tree's triangle must be hit at exactly the same distance.
                let shear = RayShear::new(o, shared::kdtree::flush_denormals(d));
                let h = shear
                    .intersect(&scene.triangles[tree.triangle as usize], 0.0, f32::MAX)
                    .expect("tree returned a triangle the ray misses");
                assert_eq!(h.t.to_bits(), brute.t.to_bits(), "ray o={o:?} d={d:?}: different triangles at different t");
            }
            assert_eq!(occluded(&scene, o, d, f32::MAX), brute.is_hit(), "occlusion disagrees for o={o:?} d={d:?}");
            brute.is_hit() as usize
        })
        .sum();
    (rays.len(), hits)
}

/// Half the rays start anywhere in the (enlarged) box in random directions; half are aimed from
/// outside at random points of random triangles, so most of them hit.
fn random_rays(c: &Compiled, n: usize, seed: u64) -> Vec<(Vec3, Vec3)> {
    let mut rng = Pcg64::seed_from_u64(seed);
    let (lo, hi) = (c.tree().bounds_min, c.tree().bounds_max);
    let center = 0.5 * (lo + hi);
    let radius = 0.5 * (hi - lo).length();
    (0..n)
        .map(|i| {
            if i % 2 == 0 {
                let o = center
                    + (hi - lo)
                        * 0.6
                        * Vec3::new(
                            rng.random_range(-1.0..1.0),
                            rng.random_range(-1.0..1.0),
                            rng.random_range(-1.0..1.0),
                        );
                (o, random_unit(&mut rng))
            } else {
                let t = &c.scene.triangles[rng.random_range(0..c.scene.triangles.len())];
                let target = random_point_on(t, &mut rng);
                let o = center + random_unit(&mut rng) * (2.0 * radius);
                (o, target - o)
            }
        })
        .collect()
}

fn mesh_case(rel: &str, seed: u64) {
    let scene = obj::load_obj(&mesh(rel)).unwrap();
    let c = compile(scene, BuildSettings::default());
    validate(c.tree(), &c.scene.triangles).unwrap();
    let (rays, hits) = check_rays(&c, &random_rays(&c, 100_000, seed));
    assert!(hits > rays / 3, "{rel}: only {hits} of {rays} rays hit: the test would prove little");
    eprintln!(
        "{rel}: {} triangles, {} nodes, depth {}, {rays} rays, {hits} hits, all equal to brute force",
        c.scene.triangles.len(),
        c.tree().nodes.len(),
        c.tree().depth
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
    // Coincident duplicate faces: ties are expected and allowed.
    mesh_case("CornellBox-Original/CornellBox-Original.obj", 3);
}

/// Rays along grid lines of a grid-aligned staircase: axis-parallel, through vertices, along
/// edges, lying in faces and in split planes.
#[test]
fn staircase_grid_line_rays_match_brute_force() {
    let (steps, width) = (16u32, 8u32);
    let c = compile(procedural::staircase(steps, width).unwrap(), BuildSettings::default());
    validate(c.tree(), &c.scene.triangles).unwrap();
    let rays = grid_line_rays(steps, width);
    let (count, hits) = check_rays(&c, &rays);
    assert!(hits > count / 4, "only {hits} of {count} grid rays hit");
    eprintln!(
        "staircase: {} triangles, {count} grid-line rays, {hits} hits, all equal to brute force",
        c.scene.triangles.len()
    );
}

#[test]
fn garbage_rays_miss_without_hanging() {
    let c = compile(procedural::staircase(4, 2).unwrap(), BuildSettings::default());
    let scene = view(&c);
    let nan = f32::NAN;
    let inf = f32::INFINITY;
    for (o, d) in [
        (Vec3::new(nan, 1.0, 1.0), Vec3::X),
        (Vec3::new(1.0, 1.0, 1.0), Vec3::new(nan, 0.0, 0.0)),
        (Vec3::new(inf, 1.0, 1.0), -Vec3::X),
        (Vec3::new(1.0, 1.0, 1.0), Vec3::new(inf, 1.0, 0.0)),
        (Vec3::new(1.0, 1.0, 1.0), Vec3::ZERO),
        (Vec3::new(1.0, 1.0, 1.0), Vec3::new(1e-40, 0.0, 0.0)),
    ] {
        assert!(!intersect(&scene, o, d, f32::MAX).is_hit(), "o={o:?} d={d:?}");
    }
}

#[test]
fn tree_is_valid_and_shallow_enough() {
    for scene in [procedural::staircase(32, 4).unwrap(), procedural::furnace(0.5, 1.0).unwrap()] {
        let c = compile(scene, BuildSettings::default());
        validate(c.tree(), &c.scene.triangles).unwrap();
        assert!(c.tree().depth <= shared::layout::KD_MAX_DEPTH);
    }
    // A corrupted tree is caught.
    let c = compile(procedural::staircase(8, 2).unwrap(), BuildSettings::default());
    let triangles = c.scene.triangles.clone();
    let mut tree = c.into_tree();
    let leaf = tree.nodes.iter().position(|n| n.is_leaf() && n.count() > 0).unwrap();
    tree.nodes[leaf] = shared::layout::KdNode::leaf(0, 0);
    assert!(validate(&tree, &triangles).is_err());
}
