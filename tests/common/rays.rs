//! Rays the traversal tests share: random unit directions, random points on triangles, and the
//! rays along the grid lines of a grid-aligned staircase.
#![allow(dead_code)]
use rand::Rng;
use rand_pcg::Pcg64;
use shared::{glam::Vec3, layout::Triangle, vecmath::xyz};

/// A direction uniform on the sphere (rejection from the cube).
pub fn random_unit(rng: &mut Pcg64) -> Vec3 {
    loop {
        let v = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        let l = v.length();
        if l > 1e-3 && l <= 1.0 {
            return v / l;
        }
    }
}

/// A point uniform on the triangle.
pub fn random_point_on(t: &Triangle, rng: &mut Pcg64) -> Vec3 {
    let (a, b): (f32, f32) = (rng.random(), rng.random());
    let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
    xyz(t.v0) + (xyz(t.v1) - xyz(t.v0)) * a + (xyz(t.v2) - xyz(t.v0)) * b
}

/// Rays along the grid lines of `procedural::staircase(steps, width)`: from every grid point
/// around it and from points half a cell off the grid, along the six axis directions and five
/// diagonals; axis-parallel, through vertices, along edges, lying in faces and in planes that
/// split the tree.
pub fn grid_line_rays(steps: u32, width: u32) -> Vec<(Vec3, Vec3)> {
    let axes = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
    let diagonals = [
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 1.0),
        Vec3::new(-1.0, 0.0, 1.0),
        Vec3::new(1.0, -1.0, -1.0),
    ];
    let n = steps as i32 + 2;
    let mut rays = Vec::new();
    for x in -1..=n {
        for y in -1..=n {
            for z in -1..=(width as i32 + 1) {
                let base = Vec3::new(x as f32, y as f32, z as f32);
                for o in
                    [base, base + Vec3::new(0.5, 0.0, 0.0), base + Vec3::new(0.0, 0.5, 0.5), base + Vec3::splat(0.5)]
                {
                    for d in axes.iter().chain(&diagonals) {
                        rays.push((o, *d));
                    }
                }
            }
        }
    }
    rays
}
