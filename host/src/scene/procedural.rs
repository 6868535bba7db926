//! Scenes made in code: analytic test cases (white furnace, single emitter) and adversarial
//! geometry for the k-d tree (a grid-aligned staircase).
use crate::scene::{diffuse, Scene};
use anyhow::Result;
use shared::glam::Vec3;
use shared::layout::Triangle;

fn tri(a: Vec3, b: Vec3, c: Vec3) -> Triangle {
    Triangle { v0: a.extend(0.0), v1: b.extend(0.0), v2: c.extend(0.0) }
}

/// Two triangles of the quad a→b→c→d, counter-clockwise seen from the front side.
pub fn quad(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> [Triangle; 2] {
    [tri(a, b, c), tri(a, c, d)]
}

/// The 12 triangles of the box [lo, hi], fronts facing inward when `inward`, else outward.
pub fn box_triangles(lo: Vec3, hi: Vec3, inward: bool) -> Vec<Triangle> {
    let p = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let (a, b) = (lo, hi);
    // Each face listed counter-clockwise as seen from outside.
    let faces = [
        [p(a.x, a.y, a.z), p(a.x, a.y, b.z), p(a.x, b.y, b.z), p(a.x, b.y, a.z)], // -x
        [p(b.x, a.y, a.z), p(b.x, b.y, a.z), p(b.x, b.y, b.z), p(b.x, a.y, b.z)], // +x
        [p(a.x, a.y, a.z), p(b.x, a.y, a.z), p(b.x, a.y, b.z), p(a.x, a.y, b.z)], // -y
        [p(a.x, b.y, a.z), p(a.x, b.y, b.z), p(b.x, b.y, b.z), p(b.x, b.y, a.z)], // +y
        [p(a.x, a.y, a.z), p(a.x, b.y, a.z), p(b.x, b.y, a.z), p(b.x, a.y, a.z)], // -z
        [p(a.x, a.y, b.z), p(b.x, a.y, b.z), p(b.x, b.y, b.z), p(a.x, b.y, b.z)], // +z
    ];
    faces
        .iter()
        .flat_map(|f| if inward { quad(f[3], f[2], f[1], f[0]) } else { quad(f[0], f[1], f[2], f[3]) })
        .collect()
}

/// A closed box whose inside is uniformly diffuse (albedo `albedo`) and uniformly emissive
/// (`emission`): the radiance everywhere inside is `emission · Σ_{k ≤ B+1} albedo^k` for B
/// indirect bounces, `emission / (1 − albedo)` without a limit.
pub fn furnace(albedo: f32, emission: f32) -> Result<Scene> {
    let tris = box_triangles(Vec3::splat(-1.0), Vec3::splat(1.0), true);
    let n = tris.len();
    Scene::new(tris, vec![0; n], vec![diffuse(Vec3::splat(albedo), Vec3::splat(emission))], vec!["furnace".into()])
}

/// A staircase of `steps` unit steps along +x, `width` wide in z, every vertex on the integer
/// grid: treads, risers and the two side walls split into unit squares, so that grid-line rays
/// run along edges and through vertices, and split planes land on faces.
pub fn staircase(steps: u32, width: u32) -> Result<Scene> {
    let mut tris = Vec::new();
    let v = |x: u32, y: u32, z: u32| Vec3::new(x as f32, y as f32, z as f32);
    for i in 0..steps {
        for k in 0..width {
            // Tread at height i+1 over x ∈ [i, i+1], facing up.
            tris.extend(quad(v(i, i + 1, k), v(i, i + 1, k + 1), v(i + 1, i + 1, k + 1), v(i + 1, i + 1, k)));
            // Riser at x = i over y ∈ [i, i+1], facing −x.
            tris.extend(quad(v(i, i, k), v(i, i, k + 1), v(i, i + 1, k + 1), v(i, i + 1, k)));
        }
        // Side walls, one unit square per cell below the tread.
        for j in 0..=i {
            tris.extend(quad(v(i, j, 0), v(i, j + 1, 0), v(i + 1, j + 1, 0), v(i + 1, j, 0)));
            tris.extend(quad(v(i, j, width), v(i + 1, j, width), v(i + 1, j + 1, width), v(i, j + 1, width)));
        }
    }
    let n = tris.len();
    Scene::new(tris, vec![0; n], vec![diffuse(Vec3::splat(0.5), Vec3::ZERO)], vec!["stairs".into()])
}

/// One emissive square of side 2 at z = 0 (front facing +z when `facing_camera`) with radiance
/// `emission`, for checking one-sided emission against its analytic value.
pub fn emitter(emission: Vec3, facing_camera: bool) -> Result<Scene> {
    let (a, b, c, d) =
        (Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(-1.0, 1.0, 0.0));
    let tris: Vec<Triangle> = if facing_camera { quad(a, b, c, d).to_vec() } else { quad(d, c, b, a).to_vec() };
    Scene::new(tris, vec![0; 2], vec![diffuse(Vec3::splat(0.5), emission)], vec!["emitter".into()])
}

/// A closed, watertight sphere of radius 1 at the origin: an icosahedron whose faces are split
/// into four `subdivisions` times, new vertices pushed onto the sphere (20·4^s triangles). Every
/// edge is shared by exactly two triangles through the very same vertex values, fronts outward.
pub fn icosphere(subdivisions: u32) -> Vec<Triangle> {
    let t = (1.0 + 5.0f64.sqrt()) / 2.0;
    let mut verts: Vec<[f64; 3]> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|v| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        [v[0] / l, v[1] / l, v[2] / l]
    })
    .collect();
    let mut faces: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoint = std::collections::HashMap::new();
        let mut mid = |a: usize, b: usize, verts: &mut Vec<[f64; 3]>| -> usize {
            *midpoint.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (p, q) = (verts[a], verts[b]);
                let m = [p[0] + q[0], p[1] + q[1], p[2] + q[2]];
                let l = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
                verts.push([m[0] / l, m[1] / l, m[2] / l]);
                verts.len() - 1
            })
        };
        let mut next = Vec::with_capacity(faces.len() * 4);
        for [a, b, c] in faces {
            let (ab, bc, ca) = (mid(a, b, &mut verts), mid(b, c, &mut verts), mid(c, a, &mut verts));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    let v = |i: usize| Vec3::new(verts[i][0] as f32, verts[i][1] as f32, verts[i][2] as f32);
    faces.iter().map(|f| tri(v(f[0]), v(f[1]), v(f[2]))).collect()
}
