//! Numerical stability under stress (issue: watertight, no self-intersection, any scale, no NaN).
//!
//! - Watertightness: rays from inside a closed sphere mesh, in random directions and aimed
//!   exactly at vertices and edge midpoints, at scales 1e-4 to 1e6 and far from the origin: none
//!   may escape.
//! - Self-intersection: rays spawned from those hits with the error-bound offset
//!   (`shared::numerics::offset_ray_origin`) never hit the triangle they leave; rays leaving the
//!   convex mesh outward hit nothing at all.
//! - The f32 watertight test against an f64 reference intersector on random rays.
//!
//! Bigger runs of the same checks: `bench/stress.sh`.
use kdtrace::{
    compile,
    kdbuild::BuildSettings,
    render::Compiled,
    scene::{
        diffuse, procedural::icosphere, round_triangle, transform::Placement, widen_triangle, Scene, WorldTriangle,
    },
};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;
use shared::{
    glam::{DVec3, Vec3},
    layout::{Triangle, TRAVERSAL_FULL_STACK, TRAVERSAL_SHORT_STACK},
    numerics::offset_ray_origin,
    raycast::closest,
    triangle::{geometric_normal, hit_point, RayShear, TriangleHit},
    vecmath::xyz,
};

/// Rays per configuration (the 10^6; `STRESS_RAYS` overrides it for bench runs).
fn rays_per_config() -> usize {
    std::env::var("STRESS_RAYS").ok().and_then(|s| s.parse().ok()).unwrap_or(1_000_000)
}

/// (scale, translation): every scale at the origin, and moved away by 1e5 (1e5·scale for scales
/// below one, where a 1e5 offset would round the whole mesh onto a single f32 point).
fn configurations() -> Vec<(f32, f32)> {
    let mut out = Vec::new();
    for s in [1e-4f32, 1.0, 1e4, 1e6] {
        out.push((s, 0.0));
        out.push((s, 1e5 * s.min(1.0)));
    }
    out
}

/// `tris` placed by `p` (in f64, each coordinate rounded to f32 once).
fn placed(tris: Vec<Triangle>, p: Placement) -> Vec<Triangle> {
    let mut world: Vec<WorldTriangle> = tris.iter().map(widen_triangle).collect();
    p.apply(&mut world);
    world.iter().map(round_triangle).collect()
}

fn sphere(scale: f32, shift: f32) -> Compiled {
    let p =
        Placement { scale: DVec3::splat(scale as f64), translate: DVec3::splat(shift as f64), ..Default::default() };
    let tris = placed(icosphere(4), p);
    let n = tris.len();
    let scene =
        Scene::new(tris, vec![0; n], vec![diffuse(Vec3::splat(0.5), Vec3::ZERO)], vec!["sphere".into()]).unwrap();
    assert_eq!(scene.triangles.len(), n, "scale {scale}, shift {shift}: triangles collapsed");
    compile(scene, BuildSettings::default())
}

fn unit(rng: &mut Pcg64) -> Vec3 {
    loop {
        let v = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        let l = v.length();
        if l > 1e-3 && l <= 1.0 {
            return v / l;
        }
    }
}

/// A ray from inside the sphere: from the exact centre or a random interior point, towards a
/// random direction, a vertex exactly, or an edge's midpoint.
fn inside_ray(c: &Compiled, rng: &mut Pcg64, scale: f32, shift: f32) -> (Vec3, Vec3) {
    let centre = Vec3::splat(shift);
    let o =
        if rng.random_range(0..8) == 0 { centre } else { centre + unit(rng) * (scale * rng.random_range(0.0..0.9f32)) };
    let t = &c.scene.triangles[rng.random_range(0..c.scene.triangles.len())];
    let (a, b) = match rng.random_range(0..3) {
        0 => (t.v0, t.v1),
        1 => (t.v1, t.v2),
        _ => (t.v2, t.v0),
    };
    let d = match rng.random_range(0..4) {
        0 => xyz(a) - o,
        1 => (xyz(a) + xyz(b)) * 0.5 - o,
        _ => unit(rng),
    };
    (o, d)
}

#[test]
fn sphere_mesh_is_closed_and_faces_outward() {
    let tris = icosphere(4);
    assert_eq!(tris.len(), 20 * 256);
    for t in &tris {
        let centroid = (xyz(t.v0) + xyz(t.v1) + xyz(t.v2)) / 3.0;
        assert!(geometric_normal(t).dot(centroid) > 0.0);
    }
}

#[test]
fn no_ray_escapes_a_closed_mesh_at_any_scale() {
    let n = rays_per_config();
    for (scale, shift) in configurations() {
        let c = sphere(scale, shift);
        let params = c.bounds_params();
        let scene = c.view(&params);
        let escapes: Vec<(Vec3, Vec3)> = (0..n)
            .into_par_iter()
            .chunks(4096)
            .flat_map_iter(|chunk| {
                let mut rng =
                    Pcg64::seed_from_u64(chunk[0] as u64 ^ scale.to_bits() as u64 ^ ((shift.to_bits() as u64) << 32));
                let scene = &scene;
                let c = &c;
                chunk
                    .into_iter()
                    .filter_map(move |i| {
                        let (o, d) = inside_ray(c, &mut rng, scale, shift);
                        let traversal = if i % 2 == 0 { TRAVERSAL_SHORT_STACK } else { TRAVERSAL_FULL_STACK };
                        (!closest(scene, traversal, o, d, f32::MAX).hit.is_hit()).then_some((o, d))
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        eprintln!("scale {scale:e}, shift {shift:e}: {n} rays from inside, {} escaped", escapes.len());
        assert!(
            escapes.is_empty(),
            "scale {scale:e}, shift {shift:e}: {} of {n} rays escaped, e.g. o={:?} d={:?}",
            escapes.len(),
            escapes[0].0,
            escapes[0].1
        );
    }
}

#[test]
fn spawned_rays_never_hit_the_surface_they_leave() {
    let configs = configurations();
    let per = rays_per_config() / configs.len();
    for (scale, shift) in configs {
        let c = sphere(scale, shift);
        let params = c.bounds_params();
        let scene = c.view(&params);
        let (rehits, outward_hits): (usize, usize) = (0..per)
            .into_par_iter()
            .map(|i| {
                let mut rng = Pcg64::seed_from_u64(i as u64 * 7919 + scale.to_bits() as u64);
                let (o, d) = inside_ray(&c, &mut rng, scale, shift);
                let hit = closest(&scene, TRAVERSAL_SHORT_STACK, o, d, f32::MAX).hit;
                assert!(hit.is_hit());
                let tri = &c.scene.triangles[hit.triangle as usize];
                let surface = hit_point(tri, &TriangleHit { t: hit.t, u: hit.u, v: hit.v, w: hit.w });
                let n = geometric_normal(tri).normalize();
                // Back inside (a bounce), and out through the surface (leaving the convex mesh).
                let inward = -n;
                let w = unit(&mut rng);
                let back = if w.dot(inward) > 0.0 { w } else { -w };
                let o_in = offset_ray_origin(surface.p, surface.error, inward);
                let again = closest(&scene, TRAVERSAL_SHORT_STACK, o_in, back, f32::MAX).hit;
                let o_out = offset_ray_origin(surface.p, surface.error, n);
                let out = closest(&scene, TRAVERSAL_SHORT_STACK, o_out, -back, f32::MAX).hit;
                ((again.triangle == hit.triangle) as usize, out.is_hit() as usize)
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        eprintln!(
            "scale {scale:e}, shift {shift:e}: {per} hits, {} re-hits inward, {} hits outward",
            rehits, outward_hits
        );
        assert_eq!((rehits, outward_hits), (0, 0), "scale {scale:e}, shift {shift:e}");
    }
}

/// Möller–Trumbore in f64: the reference the f32 watertight test is held to.
fn intersect_f64(o: [f64; 3], d: [f64; 3], t: &Triangle) -> Option<f64> {
    let v = |p: shared::glam::Vec4| [p.x as f64, p.y as f64, p.z as f64];
    let (a, b, c) = (v(t.v0), v(t.v1), v(t.v2));
    let sub = |p: [f64; 3], q: [f64; 3]| [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
    let cross =
        |p: [f64; 3], q: [f64; 3]| [p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]];
    let dot = |p: [f64; 3], q: [f64; 3]| p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
    let (e1, e2) = (sub(b, a), sub(c, a));
    let p = cross(d, e2);
    let det = dot(e1, p);
    if det == 0.0 {
        return None;
    }
    let s = sub(o, a);
    let u = dot(s, p) / det;
    let q = cross(s, e1);
    let w = dot(d, q) / det;
    let t = dot(e2, q) / det;
    (u >= 0.0 && w >= 0.0 && u + w <= 1.0 && t > 0.0).then_some(t)
}

/// The error bound of the distance the f32 watertight test computes (pbrt-v4 §6.8.4, "Conservative
/// Ray–Triangle Intersection": δt from the bounds on the sheared coordinates and edge functions),
/// evaluated in f64 from the same f32 inputs.
fn watertight_t_bound(o: Vec3, d: Vec3, t: &Triangle) -> f64 {
    let gamma = |n: f64| n * (f32::EPSILON as f64 / 2.0) / (1.0 - n * (f32::EPSILON as f64 / 2.0));
    let ad = d.abs();
    let kz = if ad.x >= ad.y && ad.x >= ad.z {
        0
    } else if ad.y >= ad.z {
        1
    } else {
        2
    };
    let (kx, ky) = ((kz + 1) % 3, (kz + 2) % 3);
    let (dx, dy, dz) = (d[kx] as f64, d[ky] as f64, d[kz] as f64);
    let (sx, sy, sz) = (dx / dz, dy / dz, 1.0 / dz);
    let sheared: Vec<[f64; 3]> = [t.v0, t.v1, t.v2]
        .iter()
        .map(|v| {
            let a = xyz(*v) - o;
            let (ax, ay, az) = (a[kx] as f64, a[ky] as f64, a[kz] as f64);
            [ax - sx * az, ay - sy * az, sz * az]
        })
        .collect();
    let max = |k: usize| sheared.iter().map(|p| p[k].abs()).fold(0.0, f64::max);
    let (max_x, max_y, max_z) = (max(0), max(1), max(2));
    let delta_z = gamma(3.0) * max_z;
    let delta_x = gamma(5.0) * (max_x + max_z);
    let delta_y = gamma(5.0) * (max_y + max_z);
    let delta_e = 2.0 * (gamma(2.0) * max_x * max_y + delta_y * max_x + delta_x * max_y);
    let (a, b, c) = (sheared[0], sheared[1], sheared[2]);
    let e = [b[0] * c[1] - b[1] * c[0], c[0] * a[1] - c[1] * a[0], a[0] * b[1] - a[1] * b[0]];
    let max_e = e.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let det = e[0] + e[1] + e[2];
    3.0 * (gamma(3.0) * max_e * max_z + delta_e * max_z + delta_z * max_e) / det.abs()
}

/// Whether `p` lies within `tol` of an edge of `t`: where two triangles meet, or where a ray
/// grazes the mesh's silhouette, f32 and f64 may each pick a different neighbour, or one of them
/// none, without either being wrong.
fn near_edge(t: &Triangle, p: Vec3, tol: f32) -> bool {
    [(t.v0, t.v1), (t.v1, t.v2), (t.v2, t.v0)].iter().any(|&(a, b)| {
        let (a, b) = (xyz(a), xyz(b));
        let e = b - a;
        let s = ((p - a).dot(e) / e.dot(e)).clamp(0.0, 1.0);
        (a + e * s - p).length() <= tol
    })
}

/// Whether the ray runs within 0.06° of the triangle's plane: there the distance along the ray is
/// ill-conditioned for any precision, and f32 and f64 may disagree on which triangle (if any) a
/// ray skimming the surface meets.
fn grazing(t: &Triangle, d: Vec3) -> bool {
    geometric_normal(t).normalize().dot(d.normalize()).abs() < 1e-3
}

#[test]
fn f32_hits_agree_with_an_f64_reference() {
    let p = Placement { scale: DVec3::splat(3.0), translate: DVec3::new(10.0, -4.0, 7.0), ..Default::default() };
    let tris = placed(icosphere(2), p);
    let n = tris.len();
    let c = compile(
        Scene::new(tris, vec![0; n], vec![diffuse(Vec3::splat(0.5), Vec3::ZERO)], vec!["s".into()]).unwrap(),
        BuildSettings::default(),
    );
    let params = c.bounds_params();
    let scene = c.view(&params);
    let rays = rays_per_config();
    let (checked, hits) = (0..rays)
        .into_par_iter()
        .map(|i| {
            let mut rng = Pcg64::seed_from_u64(i as u64);
            let target_tri = &c.scene.triangles[rng.random_range(0..n)];
            // Aimed well inside a random triangle (no edge ambiguity), or anywhere at random.
            let (u, w): (f32, f32) = (rng.random_range(0.05..0.9), rng.random_range(0.05..0.9));
            let (u, w) = if u + w > 0.95 { (0.95 - w, 0.95 - u) } else { (u, w) };
            let target = xyz(target_tri.v0) * (1.0 - u - w) + xyz(target_tri.v1) * u + xyz(target_tri.v2) * w;
            let o = Vec3::new(10.0, -4.0, 7.0) + unit(&mut rng) * rng.random_range(4.0..40.0f32);
            let aimed = i % 2 == 0;
            let d = if aimed { target - o } else { unit(&mut rng) };
            let hit = closest(&scene, TRAVERSAL_SHORT_STACK, o, d, f32::MAX).hit;
            let (o64, d64) = ([o.x as f64, o.y as f64, o.z as f64], [d.x as f64, d.y as f64, d.z as f64]);
            let mut best: Option<(f64, usize)> = None;
            for (j, t) in c.scene.triangles.iter().enumerate() {
                if let Some(t64) = intersect_f64(o64, d64, t) {
                    if best.is_none_or(|b| t64 < b.0) {
                        best = Some((t64, j));
                    }
                }
            }
            let bound_of = |tri: &Triangle| watertight_t_bound(o, d, tri);
            match best {
                Some((t64, j)) => {
                    let tol = 1e-4 * (1.0 + o.abs().max_element());
                    if !hit.is_hit() {
                        // Only a ray grazing an edge may slip past in f32.
                        let tj = &c.scene.triangles[j];
                        assert!(grazing(tj, d) || (!aimed && near_edge(tj, o + d * t64 as f32, tol)), "ray {i}: f64 hits triangle {j} at {t64} away from its edges, f32 misses");
                        return (1, 0);
                    }
                    // pbrt-v4's bound of the f32 computation, plus the f64 reference's own slop.
                    let bound = bound_of(&c.scene.triangles[hit.triangle as usize]) + 1e-12 * t64;
                    if grazing(&c.scene.triangles[hit.triangle as usize], d) || grazing(&c.scene.triangles[j], d) {
                        return (1, 1);
                    }
                    let f32_of_j = RayShear::new(o, d).intersect(&c.scene.triangles[j], 0.0, f32::MAX).map(|h| h.t);
                    let f64_of_hit = intersect_f64(o64, d64, &c.scene.triangles[hit.triangle as usize]);
                    assert!((hit.t as f64 - t64).abs() <= bound, "ray {i}: f32 t {} (tri {}, f64 there {f64_of_hit:?}) vs f64 {t64} (tri {j}, f32 there {f32_of_j:?}) (bound {bound}) o={o:?} d={d:?}", hit.t, hit.triangle);
                    if hit.triangle as usize != j {
                        // Only a tie within the bound (a ray through a shared edge) may differ.
                        let other = RayShear::new(o, d).intersect(&c.scene.triangles[j], 0.0, f32::MAX);
                        let bound_j = bound_of(&c.scene.triangles[j]) + 1e-12 * t64;
                        let tie = other.is_some_and(|h| (h.t as f64 - t64).abs() <= bound + bound_j);
                        let p = o + d * hit.t;
                        let on_shared_edge = near_edge(&c.scene.triangles[j], p, tol) && near_edge(&c.scene.triangles[hit.triangle as usize], p, tol);
                        assert!(tie || on_shared_edge, "ray {i}: f32 hit {} but f64 hit {j}, and not at an edge they share", hit.triangle);
                    }
                    (1usize, 1usize)
                }
                None => {
                    let target_grazed = grazing(target_tri, d);
                    assert!(!aimed || target_grazed, "ray {i} was aimed inside a triangle but f64 misses");
                    if hit.is_hit() {
                        // f32 hits where f64 misses only by grazing an edge: the f64 miss must be
                        // within the bound of that triangle.
                        let p = o + d * hit.t;
                        let tol = 1e-4 * (1.0 + o.abs().max_element());
                        let th = &c.scene.triangles[hit.triangle as usize];
                        assert!(grazing(th, d) || near_edge(th, p, tol), "ray {i}: f32 hits triangle {} at {} far from any edge, f64 misses", hit.triangle, hit.t);
                    }
                    (1, 0)
                }
            }
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    eprintln!("f64 reference: {checked} rays, {hits} hits; every f32 hit within its error bound");
    assert!(hits > rays / 2);
}
