//! Which triangles the CPU lanes test sixteen rays at a time (`shared::lanes::split`), and the
//! wide BVH over the others.
//!
//! The candidates are the largest triangles by area, at most `MAX_LARGE`. Taking the k largest
//! out costs every ray k / `LARGE_PER_TRAVERSAL` of a traversal (sixteen rays share each
//! triangle's test) and leaves a traversal only for the rays that meet the others' box: by the
//! surface area heuristic's argument (Goldsmith & Salmon 1987; MacDonald & Booth 1990) a ray
//! that crosses the scene's box meets a box inside it with a chance of the ratio of their
//! areas. The k of least expected cost wins where it saves at least `MIN_GAIN` of a traversal.
use super::binned::{Kind, Node2};
use super::reference::Aabb;
use super::{binary, collapse, WideBvh};
use shared::glam::Vec3;
use shared::layout::Triangle;
use shared::scene::SplitView;
use shared::vecmath::xyz;

/// At most this many large triangles: they are tested one after another, each against sixteen
/// rays.
pub const MAX_LARGE: usize = 48;

/// Large triangles whose test for sixteen rays costs about one ray's traversal of a scene worth
/// splitting. Brute force over 6 triangles a ray matches a traversal of a 36-triangle scene
/// (`lanes::brute::TRIANGLES_PER_RAY`); a traversal of a large mesh costs a few times that.
const LARGE_PER_TRAVERSAL: f64 = 200.0;

/// The least saving, in traversals a ray, for which a split is used.
const MIN_GAIN: f64 = 0.2;

/// The large triangles (ids ascending) and the BVH over the others.
pub struct Split {
    pub large: Vec<Triangle>,
    pub large_ids: Vec<u32>,
    pub rest: WideBvh,
    pub rest_min: Vec3,
    pub rest_max: Vec3,
}

impl Split {
    pub fn view(&self) -> SplitView<'_> {
        SplitView {
            large: &self.large,
            large_ids: &self.large_ids,
            rest: self.rest.view(),
            rest_min: self.rest_min,
            rest_max: self.rest_max,
        }
    }
}

/// `b` grown by triangle `t`.
fn grow(mut b: Aabb, t: &Triangle) -> Aabb {
    let (a, v, c) = (xyz(t.v0), xyz(t.v1), xyz(t.v2));
    b.grow(a.min(v).min(c), a.max(v).max(c));
    b
}

fn area(t: &Triangle) -> f64 {
    let (a, b, c) = (xyz(t.v0).as_dvec3(), xyz(t.v1).as_dvec3(), xyz(t.v2).as_dvec3());
    0.5 * (b - a).cross(c - a).length()
}

/// How many of the `k_max` largest triangles (the head of `order`, largest first) to take out,
/// by the cost model (0 for none), and the half area of all the triangles' box.
fn pick(triangles: &[Triangle], order: &[u32], k_max: usize) -> (usize, f32) {
    // The box of all triangles but the first k of `order`, for k = k_max down to 0.
    let mut rest = order[k_max..].iter().fold(Aabb::EMPTY, |b, &i| grow(b, &triangles[i as usize]));
    let mut boxes = vec![rest; k_max + 1];
    for k in (0..k_max).rev() {
        rest = grow(rest, &triangles[order[k] as usize]);
        boxes[k] = rest;
    }
    let scene_area = boxes[0].half_area();
    let whole = scene_area as f64;
    if !(whole > 0.0) {
        return (0, scene_area);
    }
    let cost = |k: usize| k as f64 / LARGE_PER_TRAVERSAL + boxes[k].half_area() as f64 / whole;
    let best = (1..=k_max).min_by(|&a, &b| cost(a).total_cmp(&cost(b))).unwrap_or(0);
    if best > 0 && cost(best) <= 1.0 - MIN_GAIN {
        (best, scene_area)
    } else {
        (0, scene_area)
    }
}

/// The triangles a split takes out and those it leaves, ids ascending in both, and the half
/// area of the scene's box.
struct Chosen {
    large_ids: Vec<u32>,
    rest_ids: Vec<u32>,
    scene_area: f32,
}

/// The large triangles the cost model favours taking out of `triangles`, and the others; `None`
/// where none pays (few triangles, which brute force takes whole, or no large ones around the
/// rest).
fn choose(triangles: &[Triangle]) -> Option<Chosen> {
    if triangles.len() <= 4 * MAX_LARGE {
        return None;
    }
    let mut order: Vec<u32> = (0..triangles.len() as u32).collect();
    let areas: Vec<f64> = triangles.iter().map(area).collect();
    // Only the largest MAX_LARGE need their order: a partial selection, then a sort of those.
    let k_max = MAX_LARGE.min(order.len() - 1);
    let by_area = |a: &u32, b: &u32| areas[*b as usize].total_cmp(&areas[*a as usize]).then(a.cmp(b));
    order.select_nth_unstable_by(k_max, by_area);
    order[..k_max].sort_unstable_by(by_area);
    let (k, scene_area) = pick(triangles, &order, k_max);
    if k == 0 {
        return None;
    }
    let mut large_ids = order[..k].to_vec();
    large_ids.sort_unstable();
    let mut rest_ids = order[k..].to_vec();
    rest_ids.sort_unstable();
    Some(Chosen { large_ids, rest_ids, scene_area })
}

/// The wide BVH over all `triangles` and, where the cost model favours one, the split. With a
/// split, both trees are collapsed from one build: the rest's binary tree, and for the whole
/// BVH a root over it and a small tree of the large triangles.
pub fn build(triangles: &[Triangle]) -> (WideBvh, Option<Split>) {
    match choose(triangles) {
        Some(ids) => {
            let (whole, split) = split(triangles, ids, true);
            (whole.expect("asked for"), Some(split))
        }
        None => (super::build(triangles), None),
    }
}

/// The split alone, for a scene whose whole BVH was built already.
pub fn build_split(triangles: &[Triangle]) -> Option<Split> {
    choose(triangles).map(|ids| split(triangles, ids, false).1)
}

/// The split of `triangles` that `chosen` names, and with `whole` the whole BVH.
fn split(triangles: &[Triangle], chosen: Chosen, whole: bool) -> (Option<WideBvh>, Split) {
    let Chosen { large_ids, rest_ids, scene_area } = chosen;
    // Spatial splits in the rest's tree are looked for as in a tree over the whole scene.
    let scene_area = Some(scene_area);
    let (rest_root, large_root) = rayon::join(
        || binary(triangles, Some(&rest_ids), scene_area),
        || whole.then(|| binary(triangles, Some(&large_ids), scene_area)),
    );
    let rest = collapse(&rest_root, triangles);
    // The root's box: that of the rest's whole triangles (spatial splits cut only below it).
    let bounds = rest_root.bounds;
    let whole = large_root.map(|large_root| {
        let mut b = rest_root.bounds;
        b.grow(large_root.bounds.lo, large_root.bounds.hi);
        collapse(&Node2 { bounds: b, kind: Kind::Inner(Box::new([rest_root, large_root])) }, triangles)
    });
    let split = Split {
        large: large_ids.iter().map(|&i| triangles[i as usize]).collect(),
        large_ids,
        rest,
        rest_min: bounds.lo,
        rest_max: bounds.hi,
    };
    (whole, split)
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared::glam::Vec4;

    fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Triangle {
        let v = |p: [f32; 3]| Vec4::new(p[0], p[1], p[2], 0.0);
        Triangle { v0: v(a), v1: v(b), v2: v(c) }
    }

    /// 400 small triangles in the middle of a box of ten unit walls (ids 400–409).
    fn walls_around_a_mesh() -> Vec<Triangle> {
        let mut tris = Vec::new();
        for i in 0..400 {
            let x = 0.4 + 0.2 * (i % 20) as f32 / 20.0;
            let y = 0.4 + 0.2 * (i / 20) as f32 / 20.0;
            tris.push(tri([x, y, 0.5], [x + 0.01, y, 0.5], [x, y + 0.01, 0.51]));
        }
        for z in [0.0f32, 1.0] {
            tris.push(tri([0.0, 0.0, z], [1.0, 0.0, z], [1.0, 1.0, z]));
            tris.push(tri([0.0, 0.0, z], [1.0, 1.0, z], [0.0, 1.0, z]));
            tris.push(tri([z, 0.0, 0.0], [z, 1.0, 0.0], [z, 1.0, 1.0]));
            tris.push(tri([z, 0.0, 0.0], [z, 1.0, 1.0], [z, 0.0, 1.0]));
            tris.push(tri([0.0, z, 0.0], [1.0, z, 0.0], [1.0, z, 1.0]));
        }
        tris
    }

    /// The walls come out, the mesh stays.
    #[test]
    fn walls_around_a_small_mesh_are_taken_out() {
        let tris = walls_around_a_mesh();
        let walls = 400;
        let (_, s) = build(&tris);
        let s = s.expect("a split");
        assert_eq!(s.large_ids, (walls..walls + 10).collect::<Vec<_>>());
        assert!(s.rest_min.cmpge(Vec3::splat(0.39)).all() && s.rest_max.cmple(Vec3::splat(0.62)).all());
        let mut ids: Vec<u32> = s.rest.indices.clone();
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids, (0..walls).collect::<Vec<_>>(), "the rest's tree holds every other triangle");
    }

    /// Sixteen rays at a time through the split (`shared::lanes::split`) against brute force over
    /// every triangle: the same closest hit bit for bit (ties between coincident faces, one
    /// large and one not, included) and the same answer for shadow rays.
    #[test]
    fn split_casts_find_what_brute_force_finds() {
        use shared::lanes::{brute, split, F, LANES, M, V3};
        use shared::layout::{RenderParams, TriangleInfo, TRAVERSAL_WIDE_BVH};
        use shared::scene::SceneView;
        let mut tris = walls_around_a_mesh();
        // A copy of a wall, coincident with it but small (so it stays in the rest), and one
        // across the mesh.
        tris.push(tri([0.3, 0.3, 0.0], [0.7, 0.3, 0.0], [0.7, 0.7, 0.0]));
        tris.push(tri([0.45, 0.2, 0.45], [0.55, 0.8, 0.5], [0.5, 0.5, 0.55]));
        let (whole, s) = build(&tris);
        let s = s.expect("a split");
        let info = vec![TriangleInfo::default(); tris.len()];
        let params = RenderParams { traversal: TRAVERSAL_WIDE_BVH, ..Default::default() };
        let mut view = SceneView::new(&params, &[], &[], &[], &tris, &info, &[], &[], &[], &[], &[]);
        view.alpha_masks = false;
        view.split = s.view();
        view.wide = whole.view();
        let mut x = 0x2545_f491u32;
        let mut r = || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            (x >> 8) as f32 / 16_777_216.0
        };
        for round in 0..300 {
            let mut lanes = |lo: f32, hi: f32| F::from_array(core::array::from_fn(|_| lo + (hi - lo) * r()));
            let o = V3::new(lanes(0.01, 0.99), lanes(0.01, 0.99), lanes(0.01, 0.99));
            let mut d = V3::new(lanes(-1.0, 1.0), lanes(-1.0, 1.0), lanes(-1.0, 1.0));
            if round % 5 == 0 {
                // Rays along the axes, from the floor's plane straight down and up.
                d.x = F::splat(0.0);
                d.y = F::splat(0.0);
            }
            let live = M::from_array(core::array::from_fn(|i| (i + round) % 7 != 0));
            assert!(split::applies(&view, &params, live));
            let got = split::closest(&view, o, d, live);
            let want = brute::cast(&tris, &[], o, d, F::splat(f32::MAX), live, false);
            let t_max = F::splat(0.9);
            let open = split::unblocked(&view, o, d, t_max, live);
            let blocked = brute::cast(&tris, &[], o, d, t_max, live, true);
            for i in (0..LANES).filter(|&i| live.test(i)) {
                let bits = |h: &shared::lanes::Hits| {
                    [h.triangle[i], h.t[i].to_bits(), h.u[i].to_bits(), h.v[i].to_bits(), h.w[i].to_bits()]
                };
                assert_eq!(bits(&got), bits(&want), "round {round}, lane {i}");
                // The whole BVH, collapsed from the same build, finds the same.
                let w = shared::wide_bvh::traverse(&view, o.lane(i), d.lane(i), f32::MAX, false);
                assert_eq!(
                    [w.triangle, w.t.to_bits()],
                    [want.triangle[i], want.t[i].to_bits()],
                    "round {round}, lane {i}"
                );
                assert_eq!(open.test(i), blocked.triangle[i] == shared::layout::NO_HIT, "round {round}, lane {i}");
            }
        }
    }

    /// Triangles of one size spread over the whole box: nothing to take out.
    #[test]
    fn an_even_mesh_is_not_split() {
        let tris: Vec<Triangle> = (0..1000)
            .map(|i| {
                let (x, y) = ((i % 32) as f32 / 32.0, (i / 32) as f32 / 32.0);
                tri([x, y, x * y], [x + 0.03, y, x * y], [x, y + 0.03, x * y])
            })
            .collect();
        assert!(build(&tris).1.is_none());
    }
}
