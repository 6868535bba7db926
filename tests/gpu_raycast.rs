//! The traversal, ray by ray, on both devices: the ray-casting kernel and the CPU cast the same
//! rays through the same tree and must return the same hit (distance bit for bit, same
//! triangle) and do the same work (nodes visited, triangles tested).
#[path = "common/paths.rs"]
mod paths;
use kdtrace::{
    kdbuild::BuildSettings,
    load,
    render::{gpu, Compiled},
};
use paths::mesh;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use shared::{
    glam::Vec3,
    layout::{RayQuery, RAY_ANY_HIT, RAY_SHORT_STACK},
    numerics::offset_ray_origin,
    raycast::cast_ray,
    triangle::{geometric_normal, interpolate},
};

fn query(o: Vec3, d: Vec3, t_max: f32, flags: u32) -> RayQuery {
    RayQuery { origin: o.extend(0.0), dir: d.extend(0.0), t_max, flags, _pad: [0; 2] }
}

/// Rays as a path tracer spawns them: from points on random triangles, offset to either side,
/// in random directions (closest hit), and shadow rays from those points to points on random
/// triangles (any hit, stopping short of the target).
fn surface_rays(c: &Compiled, n: usize, seed: u64) -> Vec<RayQuery> {
    let mut rng = Pcg64::seed_from_u64(seed);
    let tris = &c.scene.triangles;
    let point = |rng: &mut Pcg64, i: usize| {
        let (a, b): (f32, f32) = (rng.random(), rng.random());
        let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
        interpolate(&tris[i], 1.0 - a - b, a, b)
    };
    (0..n)
        .map(|k| {
            let i = rng.random_range(0..tris.len());
            let p = point(&mut rng, i);
            let n = geometric_normal(&tris[i]).normalize();
            let side = if rng.random::<bool>() { n } else { -n };
            let o = offset_ray_origin(p.p, p.error, side);
            // Every other pair of rays takes the short-stack traversal.
            let stack = if k % 4 < 2 { 0 } else { RAY_SHORT_STACK };
            if k % 2 == 0 {
                let d = loop {
                    let v = Vec3::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                    );
                    if v.length() > 1e-3 && v.length() <= 1.0 {
                        break v.normalize();
                    }
                };
                let d = if d.dot(side) < 0.0 { -d } else { d };
                query(o, d, f32::MAX, stack)
            } else {
                let j = rng.random_range(0..tris.len());
                let q = point(&mut rng, j).p;
                query(o, q - o, 1.0 - 1e-4, RAY_ANY_HIT | stack)
            }
        })
        .collect()
}

fn cast_on_both(c: &Compiled, rays: &[RayQuery], what: &str) {
    let g = gpu::Gpu::lavapipe().unwrap_or_else(|e| panic!("{e:#}"));
    let params = c.bounds_params();
    let scene = c.view(&params);
    let cpu: Vec<_> = rays.iter().map(|q| cast_ray(&scene, q)).collect();
    let gpu = g.cast(c, rays).unwrap();
    assert_eq!(cpu.len(), gpu.len());
    let mut hits = 0;
    let mut mismatches = Vec::new();
    for (i, (a, b)) in cpu.iter().zip(&gpu).enumerate() {
        hits += (a.triangle != u32::MAX) as usize;
        if (a.t.to_bits(), a.triangle, a.nodes, a.tests, a.restarts)
            != (b.t.to_bits(), b.triangle, b.nodes, b.tests, b.restarts)
        {
            mismatches.push(i);
        }
    }
    eprintln!("{what} on {}: {} rays, {hits} hits, {} differ", g.adapter.name, rays.len(), mismatches.len());
    for &i in mismatches.iter().take(5) {
        eprintln!("  ray {i}: {:?}\n    cpu {:?}\n    gpu {:?}", rays[i], cpu[i], gpu[i]);
    }
    assert!(hits > rays.len() / 10, "{what}: too few hits ({hits}) for a meaningful test");
    assert!(mismatches.is_empty(), "{what}: {} of {} rays differ between CPU and GPU", mismatches.len(), rays.len());
}

#[test]
fn surface_rays_agree_on_the_water_box() {
    let c = load(&mesh("CornellBox-Water/CornellBox-Water.obj"), BuildSettings::default()).unwrap().compiled;
    cast_on_both(&c, &surface_rays(&c, 20_000, 3), "CornellBox-Water");
}

#[test]
fn surface_rays_agree_on_the_bunny() {
    let c = load(&mesh("bunny-stanford-bun_zipper/bun_zipper.obj"), BuildSettings::default()).unwrap().compiled;
    cast_on_both(&c, &surface_rays(&c, 20_000, 4), "bunny");
}
