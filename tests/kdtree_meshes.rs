//! The SAH tree of every mesh in `tests/data/meshes` passes `validate`, stays within the depth
//! and reference budgets, and does not depend on the number of build threads. (`bench/kdtree.sh`
//! builds and validates the larger public set the benchmarks read.)
#[path = "common/paths.rs"]
mod paths;
use kdtrace::{
    kdbuild::{build, stats, validate, BuildSettings},
    scene::obj::load_obj,
};
use paths::{mesh, repo};
use shared::layout::KD_MAX_DEPTH;
use std::path::PathBuf;

fn meshes() -> Vec<PathBuf> {
    let mut out = Vec::new();
    for dir in std::fs::read_dir(repo("tests/data/meshes")).unwrap() {
        let dir = dir.unwrap().path();
        if !dir.is_dir() {
            continue;
        }
        for f in std::fs::read_dir(&dir).unwrap() {
            let f = f.unwrap().path();
            if f.extension().is_some_and(|e| e == "obj") {
                out.push(f);
            }
        }
    }
    out.sort();
    out
}

#[test]
fn every_test_mesh_builds_a_valid_tree() {
    let all = meshes();
    assert!(all.len() >= 6, "expected the six meshes of tests/data/meshes, found {}", all.len());
    let settings = BuildSettings::default();
    for path in all {
        let scene = load_obj(&path).unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
        let tree = build(&scene.triangles, scene.bounds_min, scene.bounds_max, settings);
        validate(&tree, &scene.triangles).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let st = stats(&tree, scene.triangles.len(), &settings);
        assert!(st.max_depth <= KD_MAX_DEPTH.min(settings.depth_limit(scene.triangles.len())));
        assert!(st.total_refs as f64 <= settings.max_refs_factor as f64 * scene.triangles.len() as f64);
        eprintln!(
            "{}: {} triangles, {} nodes, depth {}, {:.2} refs/leaf, SAH cost {:.1}",
            path.display(),
            st.triangles,
            st.nodes,
            st.max_depth,
            st.mean_leaf_refs,
            st.sah_cost
        );
    }
}

#[test]
fn the_tree_does_not_depend_on_the_thread_count() {
    let scene = load_obj(&mesh("bunny-stanford-bun_zipper/bun_zipper.obj")).unwrap();
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| build(&scene.triangles, scene.bounds_min, scene.bounds_max, BuildSettings::default()))
    };
    let (one, three) = (on(1), on(3));
    assert!(one.nodes.len() > 10_000);
    assert_eq!(one.nodes, three.nodes);
    assert_eq!(one.indices, three.indices);
}
