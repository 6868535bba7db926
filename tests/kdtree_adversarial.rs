//! The SAH tree on inputs built to break it: degenerate geometry (coplanar, flat on an axis,
//! zero-area, a single triangle, 10^5 copies of one triangle) must give a valid, bounded tree
//! quickly; rays lying exactly in split planes and rays starting on triangle edges must get
//! exactly the brute-force hit. The CPU path's wide BVH is held to the same on the same
//! inputs: its depth within `layout::WIDE_MAX_DEPTH`, its hits brute force's.
#[path = "common/paths.rs"]
mod paths;
use kdtrace::{
    compile,
    kdbuild::{build, is_aligned, stats, validate, BuildSettings, Builder, KdTree},
    render::Compiled,
    scene::obj,
};
use paths::mesh;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;
use shared::{
    glam::Vec3,
    kdtree::{intersect, intersect_brute_force, test_leaf_blocks, test_leaf_each, Hit},
    layout::{KdNode, Triangle, BLOCK_WIDTH, KD_MAX_DEPTH},
    triangle::RayShear,
    vecmath::xyz,
};
use std::time::Instant;

fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Triangle {
    Triangle { v0: Vec3::from(a).extend(0.0), v1: Vec3::from(b).extend(0.0), v2: Vec3::from(c).extend(0.0) }
}

fn bounds(tris: &[Triangle]) -> (Vec3, Vec3) {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for t in tris {
        for v in [t.v0, t.v1, t.v2] {
            lo = lo.min(xyz(v));
            hi = hi.max(xyz(v));
        }
    }
    (lo, hi)
}

/// Builds with both builders, validates, and returns the SAH tree.
fn build_checked(what: &str, tris: &[Triangle]) -> KdTree {
    let (lo, hi) = bounds(tris);
    let mut sah = None;
    for builder in [Builder::Sah, Builder::Median] {
        let settings = BuildSettings { builder, ..Default::default() };
        let t0 = Instant::now();
        let tree = build(tris, lo, hi, settings);
        let secs = t0.elapsed().as_secs_f64();
        validate(&tree, tris).unwrap_or_else(|e| panic!("{what} ({builder:?}): {e}"));
        assert!(tree.depth <= KD_MAX_DEPTH, "{what}: depth {}", tree.depth);
        assert!(is_aligned(&tree), "{what} ({builder:?}): the index list is not laid out in blocks");
        let st = stats(&tree, tris.len(), &settings);
        eprintln!(
            "{what} ({builder:?}): {} triangles, {} nodes, depth {}, {} refs, SAH cost {:.1}, {secs:.3} s",
            tris.len(),
            st.nodes,
            st.max_depth,
            st.total_refs,
            st.sah_cost
        );
        assert!(secs < 30.0, "{what}: build took {secs} s");
        if builder == Builder::Sah {
            sah = Some(tree);
        }
    }
    sah.unwrap()
}

/// Random rays (aimed at random triangles, and from random points in random directions) must get
/// exactly the brute-force hit, through both traversals.
fn traversal_matches_brute_force(what: &str, tris: &[Triangle], rays: usize) {
    let n = tris.len();
    let scene = kdtrace::scene::Scene::new(
        tris.to_vec(),
        vec![0; n],
        vec![kdtrace::scene::diffuse(Vec3::splat(0.5), Vec3::ZERO)],
        vec!["m".into()],
    )
    .unwrap();
    let c = compile(scene, BuildSettings::default());
    let depth = c.wide_bvh().depth();
    assert!(depth <= shared::layout::WIDE_MAX_DEPTH, "{what}: wide BVH depth {depth}");
    let params = c.bounds_params();
    let view = c.view(&params);
    // Flat scenes get origins off their plane: every axis spans at least the largest extent.
    let (lo, hi) = (c.tree().bounds_min, c.tree().bounds_max);
    let ext = (hi - lo).max(Vec3::splat((hi - lo).max_element()));
    let lo = (lo + hi) * 0.5 - ext * 0.5;
    let hits: usize = (0..rays)
        .into_par_iter()
        .map(|i| {
            let mut rng = Pcg64::seed_from_u64(i as u64);
            let o = lo
                + ext
                    * Vec3::new(rng.random_range(-0.5..1.5), rng.random_range(-0.5..1.5), rng.random_range(-0.5..1.5));
            let t = &c.scene.triangles[rng.random_range(0..c.scene.triangles.len())];
            let d = if i % 2 == 0 {
                (xyz(t.v0) + xyz(t.v1) + xyz(t.v2)) / 3.0 - o
            } else {
                Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))
            };
            let b = intersect_brute_force(&view, o, d, f32::MAX);
            for traversal in [
                shared::layout::TRAVERSAL_FULL_STACK,
                shared::layout::TRAVERSAL_SHORT_STACK,
                shared::layout::TRAVERSAL_WIDE_BVH,
            ] {
                let a = shared::raycast::closest(&view, traversal, o, d, f32::MAX).hit;
                assert_eq!(
                    a.t.to_bits(),
                    b.t.to_bits(),
                    "{what}: o={o:?} d={d:?}: tree {} (tri {}), brute force {} (tri {})",
                    a.t,
                    a.triangle,
                    b.t,
                    b.triangle
                );
            }
            b.is_hit() as usize
        })
        .sum();
    eprintln!("{what}: {rays} rays, {hits} hits, the three traversals equal to brute force");
    assert!(hits > rays / 4, "{what}: too few hits ({hits})");
}

fn grid_of_triangles(n: usize, z: impl Fn(usize, usize) -> f32) -> Vec<Triangle> {
    let mut out = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let (x, y) = (i as f32, j as f32);
            out.push(tri([x, y, z(i, j)], [x + 1.0, y, z(i, j)], [x, y + 1.0, z(i, j)]));
        }
    }
    out
}

#[test]
fn all_triangles_in_one_axis_aligned_plane() {
    let tris = grid_of_triangles(60, |_, _| 0.5);
    build_checked("flat on z = 0.5", &tris);
    traversal_matches_brute_force("flat on z = 0.5", &tris, 20_000);
}

#[test]
fn all_triangles_coplanar_in_a_tilted_plane() {
    let tris: Vec<Triangle> = grid_of_triangles(50, |_, _| 0.0)
        .into_iter()
        .map(|t| {
            let f = |v: shared::glam::Vec4| Vec3::new(v.x, v.y, 0.3 * v.x - 0.7 * v.y + 2.0).extend(0.0);
            Triangle { v0: f(t.v0), v1: f(t.v1), v2: f(t.v2) }
        })
        .collect();
    build_checked("coplanar tilted", &tris);
    traversal_matches_brute_force("coplanar tilted", &tris, 5_000);
}

#[test]
fn zero_area_triangles_points_and_lines() {
    let mut tris = grid_of_triangles(20, |i, j| (i * j) as f32 * 0.01);
    for i in 0..500 {
        let x = i as f32 * 0.04;
        tris.push(tri([x, 1.0, 0.5], [x, 1.0, 0.5], [x, 1.0, 0.5])); // a point
        tris.push(tri([x, 0.0, 0.0], [x + 1.0, 1.0, 1.0], [x + 2.0, 2.0, 2.0])); // a line
        tris.push(tri([x, 3.0, 0.25], [x, 5.0, 0.25], [x, 4.0, 0.25])); // a segment along y
    }
    build_checked("zero-area mixed in", &tris);
    traversal_matches_brute_force("zero-area mixed in", &tris, 5_000);
}

#[test]
fn one_triangle() {
    let tree = build_checked("one triangle", &[tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])]);
    assert_eq!(tree.nodes.len(), 1, "a single triangle needs no split");
}

#[test]
fn a_hundred_thousand_copies_of_one_triangle() {
    let t = tri([0.0, 0.0, 0.0], [1.0, 0.2, 0.1], [0.3, 1.0, 0.5]);
    let tris = vec![t; 100_000];
    let tree = build_checked("10^5 copies", &tris);
    assert!(tree.nodes.len() <= 64, "copies cannot be separated; {} nodes", tree.nodes.len());
    traversal_matches_brute_force("10^5 copies", &tris, 2_000);
}

#[test]
fn many_triangles_sharing_one_vertex_and_needles() {
    let mut tris = Vec::new();
    for i in 0..2000 {
        let a = i as f32 * 0.003;
        tris.push(tri([0.0, 0.0, 0.0], [a.cos(), a.sin(), 0.1], [(a + 0.002).cos(), (a + 0.002).sin(), 0.1]));
        // Needles: long and a hair wide.
        tris.push(tri([a, 2.0, 0.0], [a + 5.0, 2.0, 1.0], [a + 5.0, 2.0 + 1e-5, 1.0]));
    }
    let tree = build_checked("fan and needles", &tris);
    let refs = stats(&tree, tris.len(), &BuildSettings::default()).total_refs;
    let cap = BuildSettings::default().max_refs_factor as f64 * tris.len() as f64;
    assert!(refs as f64 <= cap, "{refs} references exceed the budget of {cap}");
    traversal_matches_brute_force("fan and needles", &tris, 20_000);
}

fn check_exact(c: &Compiled, rays: &[(Vec3, Vec3)], what: &str) -> usize {
    let params = c.bounds_params();
    let scene = c.view(&params);
    rays.par_iter()
        .map(|&(o, d)| {
            let a = intersect(&scene, o, d, f32::MAX);
            let b = intersect_brute_force(&scene, o, d, f32::MAX);
            assert_eq!(
                a.t.to_bits(),
                b.t.to_bits(),
                "{what}: o={o:?} d={d:?}: tree {} (tri {}), brute force {} (tri {})",
                a.t,
                a.triangle,
                b.t,
                b.triangle
            );
            b.is_hit() as usize
        })
        .sum()
}

/// Rays lying exactly in split planes of the SAH tree (the direction has no component across
/// the plane), and rays crossing planes exactly at a vertex.
#[test]
fn rays_in_split_planes_and_from_triangle_edges_match_brute_force() {
    let scene = obj::load_obj(&mesh("dragon-23k/dragon.obj")).unwrap();
    let c = compile(scene, BuildSettings::default());
    let (lo, hi) = (c.tree().bounds_min, c.tree().bounds_max);
    let mut rng = Pcg64::seed_from_u64(11);
    let planes: Vec<(usize, f32)> =
        c.tree().nodes.iter().filter(|n| !n.is_leaf()).map(|n| (n.axis() as usize, n.split())).collect();
    let mut rays = Vec::new();
    for _ in 0..20_000 {
        let (k, s) = planes[rng.random_range(0..planes.len())];
        let mut o = lo + (hi - lo) * Vec3::new(rng.random(), rng.random(), rng.random());
        o[k] = s;
        let mut d = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        d[k] = 0.0;
        rays.push((o, d));
    }
    let in_plane_hits = check_exact(&c, &rays, "in split plane");
    rays.clear();
    for _ in 0..20_000 {
        let t = &c.scene.triangles[rng.random_range(0..c.scene.triangles.len())];
        let (a, b) = match rng.random_range(0..3) {
            0 => (t.v0, t.v1),
            1 => (t.v1, t.v2),
            _ => (t.v2, t.v0),
        };
        let f: f32 = rng.random();
        let o = xyz(a) + (xyz(b) - xyz(a)) * f;
        let d = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        rays.push((o, d));
        // And aimed at a vertex from outside.
        let target = xyz(t.v0);
        let from = target
            + Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))
                * (hi - lo).length();
        rays.push((from, target - from));
    }
    let edge_hits = check_exact(&c, &rays, "edge or vertex");
    eprintln!("dragon-23k: {in_plane_hits} of 20000 in-plane rays hit, {edge_hits} of 40000 edge/vertex rays hit; all equal to brute force");
    assert!(in_plane_hits > 1000 && edge_hits > 20_000, "too few hits to prove anything");
}

/// The SAH tree must beat the spatial median on its own cost measure, by a clear margin on a
/// real mesh (Wald & Havran report about 2× fewer expected operations).
#[test]
fn sah_tree_is_cheaper_than_the_median_tree() {
    let scene = obj::load_obj(&mesh("bunny-stanford-bun_zipper/bun_zipper.obj")).unwrap();
    let n = scene.triangles.len();
    let sah_settings = BuildSettings::default();
    let median_settings = BuildSettings { builder: Builder::Median, ..Default::default() };
    let sah = stats(&compile(scene.clone(), sah_settings).into_tree(), n, &sah_settings);
    let median = stats(&compile(scene, median_settings).into_tree(), n, &sah_settings);
    eprintln!("bunny: SAH cost {:.1} (SAH tree) vs {:.1} (median tree)", sah.sah_cost, median.sah_cost);
    assert!(sah.sah_cost < 0.75 * median.sah_cost);
}

/// The CPU's defaults (a leaf test covers eight triangles) and the GPU's (`for_gpu`: one
/// triangle per test, Wald & Havran's costs) must each give the tree that is cheaper under their
/// own cost model: the block width reaches the sweep's cost function and the termination rule.
#[test]
fn each_leaf_cost_model_builds_the_tree_cheapest_under_it() {
    let scene = obj::load_obj(&mesh("bunny-stanford-bun_zipper/bun_zipper.obj")).unwrap();
    let n = scene.triangles.len();
    let cpu = BuildSettings::default();
    let gpu = BuildSettings::for_gpu();
    assert_eq!((cpu.leaf_block, gpu.leaf_block), (BLOCK_WIDTH, 1));
    let tree_cpu = compile(scene.clone(), cpu).into_tree();
    let tree_gpu = compile(scene, gpu).into_tree();
    let cost = |t: &KdTree, s: &BuildSettings| stats(t, n, s).sah_cost;
    let (cc, cg, gc, gg) = (cost(&tree_cpu, &cpu), cost(&tree_gpu, &cpu), cost(&tree_cpu, &gpu), cost(&tree_gpu, &gpu));
    eprintln!(
        "bunny: CPU model {cc:.1} (CPU tree) vs {cg:.1} (GPU tree); GPU model {gc:.1} vs {gg:.1}; nodes {} vs {}",
        tree_cpu.nodes.len(),
        tree_gpu.nodes.len()
    );
    assert!(cc < 0.9 * cg, "the CPU tree must be clearly cheaper under the CPU model");
    assert!(gg < 0.9 * gc, "the GPU tree must be clearly cheaper under the GPU model");
}

/// A tree whose leaves do not start on block boundaries (a .kdc file of the old layout, a
/// builder elsewhere) is laid out anew by `Compiled::new`, keeping every leaf's triangles, and
/// its hits stay exactly the brute-force ones.
#[test]
fn unaligned_leaves_are_laid_out_anew_and_stay_exact() {
    let scene = obj::load_obj(&mesh("bunny-stanford-bun_zipper/bun_zipper.obj")).unwrap();
    let mut tree = compile(scene.clone(), BuildSettings::default()).into_tree();
    assert!(is_aligned(&tree));
    // Pack the runs back to back, as the list was before blocks.
    let mut packed = Vec::new();
    let mut runs = Vec::new();
    for n in tree.nodes.iter_mut().filter(|n| n.is_leaf()) {
        let run = tree.indices[n.first_index() as usize..(n.first_index() + n.count()) as usize].to_vec();
        *n = KdNode::leaf(packed.len() as u32, n.count());
        packed.extend_from_slice(&run);
        runs.push(run);
    }
    tree.indices = packed;
    assert!(!is_aligned(&tree), "packing must break the layout, or this test checks nothing");
    let c = Compiled::new(scene, tree);
    assert!(is_aligned(c.tree()));
    let after: Vec<Vec<u32>> = c
        .tree()
        .nodes
        .iter()
        .filter(|n| n.is_leaf())
        .map(|n| c.tree().indices[n.first_index() as usize..(n.first_index() + n.count()) as usize].to_vec())
        .collect();
    assert_eq!(after, runs, "laying out must keep every leaf's triangles in order");
    let mut rng = Pcg64::seed_from_u64(5);
    let (lo, hi) = (c.tree().bounds_min, c.tree().bounds_max);
    let rays: Vec<(Vec3, Vec3)> = (0..20_000)
        .map(|_| {
            let o = lo
                + (hi - lo)
                    * Vec3::new(rng.random_range(-0.2..1.2), rng.random_range(-0.2..1.2), rng.random_range(-0.2..1.2));
            let t = &c.scene.triangles[rng.random_range(0..c.scene.triangles.len())];
            (o, (xyz(t.v0) + xyz(t.v1) + xyz(t.v2)) / 3.0 - o)
        })
        .collect();
    let hits = check_exact(&c, &rays, "bunny, laid out anew");
    assert!(hits > 10_000, "too few hits: {hits}");
}

/// The CPU's eight-lane leaf test against the one-by-one test the GPU runs, leaf by leaf on the
/// bunny's tree (empty leaves, whose runs need not start a block, included): the same hit, the
/// same count of tests and the same verdict, for closest and any hit.
#[test]
fn block_leaf_test_equals_the_one_by_one_test_on_every_leaf() {
    let scene = obj::load_obj(&mesh("bunny-stanford-bun_zipper/bun_zipper.obj")).unwrap();
    let c = compile(scene, BuildSettings::default());
    let params = c.bounds_params();
    let view = c.view(&params);
    let leaves: Vec<KdNode> = c.tree().nodes.iter().copied().filter(|n| n.is_leaf()).collect();
    assert!(
        leaves.iter().any(|n| n.count() == 0 && n.first_index() % BLOCK_WIDTH != 0),
        "no unaligned empty leaf: the empty case goes untested"
    );
    let (lo, hi) = (c.tree().bounds_min, c.tree().bounds_max);
    let mut rng = Pcg64::seed_from_u64(17);
    let mut hits = 0;
    for _ in 0..300 {
        let o = lo
            + (hi - lo)
                * Vec3::new(rng.random_range(-0.2..1.2), rng.random_range(-0.2..1.2), rng.random_range(-0.2..1.2));
        let t = &c.scene.triangles[rng.random_range(0..c.scene.triangles.len())];
        let d = (xyz(t.v0) + xyz(t.v1) + xyz(t.v2)) / 3.0 - o;
        let shear = RayShear::new(o, d);
        for &n in &leaves {
            for any_hit in [false, true] {
                let t_max = if any_hit { 1.0 } else { f32::MAX };
                let (mut a, mut b) = (Hit::miss(t_max), Hit::miss(t_max));
                let (mut ta, mut tb) = (0, 0);
                let da = test_leaf_blocks(&view, &shear, n, &mut a, &mut ta, any_hit);
                let db = test_leaf_each(&view, &shear, n, &mut b, &mut tb, any_hit);
                assert_eq!(
                    (da, ta, a.triangle, a.t.to_bits(), a.u.to_bits()),
                    (db, tb, b.triangle, b.t.to_bits(), b.u.to_bits()),
                    "leaf {n:?}, any hit {any_hit}, o={o:?} d={d:?}"
                );
                hits += a.is_hit() as usize;
            }
        }
    }
    assert!(hits > 300, "too few leaf hits to mean anything: {hits}");
}
