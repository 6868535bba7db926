//! The binary BVH the wide tree is collapsed from: top-down, split by the surface area
//! heuristic over 16 bins of the references' centroids per axis (Wald, "On fast Construction of
//! SAH-based Bounding Volume Hierarchies", RT 2007), or, where that split leaves the children's
//! boxes overlapping, at a plane that cuts the triangles straddling it (`spatial`), whichever
//! costs less; the two halves are built in parallel.
//!
//! A reference is a triangle id and the box of the part of that triangle the node holds. A leaf
//! holds at most `LEAF_SIZE` references, one block of the CPU's eight-lane test: a node with more
//! is always split, by the heuristic where it finds a split, else at the middle of its centroids'
//! order. Below `SAH_DEPTH` every split is that middle one, so the depth stays below
//! `SAH_DEPTH` + log2(n) whatever the geometry.
use super::reference::{Aabb, Ref};
use super::spatial;
use shared::glam::Vec3;

/// Triangles a leaf may hold: a `TriBlock`.
pub const LEAF_SIZE: usize = shared::layout::BLOCK_WIDTH as usize;
const BINS: usize = 16;
/// Depth below which splits stop looking at the heuristic.
const SAH_DEPTH: u32 = 48;
/// Triangles below which a node's two halves are built on this thread.
const PARALLEL_MIN: usize = 4096;
/// The overlap of the object split's children, as a fraction of the root's area, above which a
/// spatial split is looked for (Stich et al.'s α). Their 1e-5 finds the same tree on Sponza at
/// twice the build time: the splits that matter are near the top.
const OVERLAP: f32 = 1e-3;
/// References that spatial splits may add, per triangle.
pub const DUPLICATES: f32 = 0.3;

/// What the builder reads: every triangle's corners and the root's area.
pub struct Input<'a> {
    pub tris: &'a [[Vec3; 3]],
    pub root_area: f32,
}

/// A node of the binary tree: its box, and either the triangle ids of a leaf or two children.
pub struct Node2 {
    pub bounds: Aabb,
    pub kind: Kind,
}

pub enum Kind {
    Leaf { ids: Vec<u32> },
    Inner(Box<[Node2; 2]>),
}

/// Builds the tree over all of `tris` (their ids are their positions) as if entered at `depth`;
/// spatial splits may add at most `budget` references. For triangles that are part of a scene,
/// `scene_area` (the half area of the scene's box) sets where spatial splits are looked for, as
/// in a tree over the whole scene; `None` takes their own box.
pub fn build_in(tris: &[[Vec3; 3]], depth: u32, budget: usize, scene_area: Option<f32>) -> Node2 {
    use rayon::prelude::*;
    let refs: Vec<Ref> = tris
        .par_iter()
        .enumerate()
        .map(|(id, &[a, b, c])| Ref { id: id as u32, b: Aabb { lo: a.min(b).min(c), hi: a.max(b).max(c) } })
        .collect();
    let mut root = Aabb::EMPTY;
    refs.iter().for_each(|r| root.grow(r.b.lo, r.b.hi));
    let root_area = scene_area.unwrap_or(root.half_area());
    build(&Input { tris, root_area }, refs, depth, budget)
}

/// Builds the tree over `refs`; spatial splits may add at most `budget` references below.
pub fn build(input: &Input, mut refs: Vec<Ref>, depth: u32, budget: usize) -> Node2 {
    let mut bounds = Aabb::EMPTY;
    let mut centres = Aabb::EMPTY;
    for r in refs.iter() {
        bounds.grow(r.b.lo, r.b.hi);
        centres.grow(r.b.centre(), r.b.centre());
    }
    if refs.len() <= LEAF_SIZE {
        return Node2 { bounds, kind: Kind::Leaf { ids: refs.iter().map(|r| r.id).collect() } };
    }
    let n = refs.len();
    let object = if depth < SAH_DEPTH { object_split(&refs, &centres) } else { None };
    let spatial = match object {
        Some(o) if o.overlap > OVERLAP * input.root_area => {
            spatial::find(input.tris, &refs, &bounds, budget, n >= PARALLEL_MIN).filter(|s| s.cost < o.cost)
        }
        _ => None,
    };
    // A spatial split whose cuts fell otherwise than its bins foretold (rounding at a bin's
    // border) and left a side empty or whole is dropped for the object split.
    let cut = spatial
        .map(|s| spatial::partition(input.tris, &refs, s))
        .filter(|(l, r)| !l.is_empty() && !r.is_empty() && l.len() < n && r.len() < n);
    let (left, right) = match cut {
        Some(sides) => sides,
        None => {
            let mid = object.map_or(0, |o| partition_by_bin(&mut refs, &centres, o));
            let mid = if mid == 0 || mid == n { middle_split(&mut refs, &centres) } else { mid };
            let right = refs.split_off(mid);
            (refs, right)
        }
    };
    // What the split did not spend goes to the two sides in proportion to their size.
    let left_over = budget.saturating_sub(left.len() + right.len() - n);
    let left_budget = left_over * left.len() / (left.len() + right.len());
    let right_budget = left_over - left_budget;
    let (a, b) = if n >= PARALLEL_MIN {
        rayon::join(|| build(input, left, depth + 1, left_budget), || build(input, right, depth + 1, right_budget))
    } else {
        (build(input, left, depth + 1, left_budget), build(input, right, depth + 1, right_budget))
    };
    Node2 { bounds, kind: Kind::Inner(Box::new([a, b])) }
}

/// The heuristic's best split over the centroid bins of one axis, and how much its two
/// children's boxes overlap (half area).
#[derive(Clone, Copy)]
struct ObjectSplit {
    cost: f32,
    axis: usize,
    bin: usize,
    overlap: f32,
}

/// The best object split over the bins of each axis, or `None` when the centroids do not
/// separate.
fn object_split(refs: &[Ref], centres: &Aabb) -> Option<ObjectSplit> {
    let per_axis = |axis: usize| object_split_on(refs, centres, axis);
    let best = if refs.len() >= PARALLEL_MIN {
        use rayon::prelude::*;
        (0..3).into_par_iter().map(per_axis).collect::<Vec<_>>()
    } else {
        (0..3).map(per_axis).collect()
    };
    let (mut s, l, r) = best.into_iter().flatten().reduce(|a, b| if b.0.cost < a.0.cost { b } else { a })?;
    let common = l.intersect(&r);
    s.overlap = if common.is_empty() { 0.0 } else { common.half_area() };
    Some(s)
}

/// The best object split on one axis, with its children's boxes.
fn object_split_on(refs: &[Ref], centres: &Aabb, axis: usize) -> Option<(ObjectSplit, Aabb, Aabb)> {
    let (lo, ext) = (centres.lo[axis], centres.hi[axis] - centres.lo[axis]);
    if !(ext > 0.0) {
        return None;
    }
    let scale = BINS as f32 / ext;
    let mut boxes = [Aabb::EMPTY; BINS];
    let mut counts = [0usize; BINS];
    for r in refs {
        let b = (((r.b.centre()[axis] - lo) * scale) as usize).min(BINS - 1);
        boxes[b].grow(r.b.lo, r.b.hi);
        counts[b] += 1;
    }
    // Sweep from the right, then from the left: cost = A_L·N_L + A_R·N_R.
    let mut right_box = [Aabb::EMPTY; BINS];
    let mut acc = Aabb::EMPTY;
    for b in (1..BINS).rev() {
        acc.grow(boxes[b].lo, boxes[b].hi);
        right_box[b] = acc;
    }
    let mut best: Option<(ObjectSplit, Aabb, Aabb)> = None;
    let mut left = Aabb::EMPTY;
    let mut n_left = 0usize;
    for b in 0..BINS - 1 {
        left.grow(boxes[b].lo, boxes[b].hi);
        n_left += counts[b];
        let n_right = refs.len() - n_left;
        if n_left == 0 || n_right == 0 {
            continue;
        }
        let cost = left.half_area() * n_left as f32 + right_box[b + 1].half_area() * n_right as f32;
        if best.as_ref().is_none_or(|(s, _, _)| cost < s.cost) {
            best = Some((ObjectSplit { cost, axis, bin: b + 1, overlap: 0.0 }, left, right_box[b + 1]));
        }
    }
    best
}

/// Partitions `refs` in place by the split's bin; returns the size of the left part.
fn partition_by_bin(refs: &mut [Ref], centres: &Aabb, s: ObjectSplit) -> usize {
    let (lo, scale) = (centres.lo[s.axis], BINS as f32 / (centres.hi[s.axis] - centres.lo[s.axis]));
    let left_of = |r: &Ref| (((r.b.centre()[s.axis] - lo) * scale) as usize).min(BINS - 1) < s.bin;
    let (mut i, mut j) = (0usize, refs.len());
    while i < j {
        if left_of(&refs[i]) {
            i += 1;
        } else {
            j -= 1;
            refs.swap(i, j);
        }
    }
    i
}

/// Splits at the middle of the centroids' order along the widest axis (ties by id, so the
/// tree does not depend on the input order's accidents).
fn middle_split(refs: &mut [Ref], centres: &Aabb) -> usize {
    let extent = centres.hi - centres.lo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = refs.len() / 2;
    refs.select_nth_unstable_by(mid, |a, b| {
        let (ca, cb) = (a.b.centre()[axis], b.b.centre()[axis]);
        ca.total_cmp(&cb).then(a.id.cmp(&b.id))
    });
    mid
}

#[cfg(test)]
mod tests {
    use super::*;

    fn depth(n: &Node2) -> u32 {
        match &n.kind {
            Kind::Leaf { .. } => 1,
            Kind::Inner(kids) => 1 + depth(&kids[0]).max(depth(&kids[1])),
        }
    }

    fn leaves<'a>(n: &'a Node2, out: &mut Vec<(&'a [u32], Aabb)>) {
        match &n.kind {
            Kind::Leaf { ids } => out.push((ids, n.bounds)),
            Kind::Inner(kids) => kids.iter().for_each(|k| leaves(k, out)),
        }
    }

    /// Triangles at exponentially growing distances: the best SAH plane peels the few farthest
    /// off at each split, a chain far deeper than a balanced tree, yet within the bound; past
    /// `SAH_DEPTH` (the build entered there) the middle splits are balanced. Without a budget for
    /// spatial splits every triangle lands in exactly one leaf of at most `LEAF_SIZE`.
    #[test]
    fn a_chain_of_peeled_triangles_stays_within_the_depth_bound() {
        let n = 300usize;
        let tris: Vec<[Vec3; 3]> = (0..n)
            .map(|i| {
                let x = 1.3f32.powi(i as i32);
                [Vec3::new(x, 0.0, 0.0), Vec3::new(x * 1.001, 1.0, 0.0), Vec3::new(x, 1.0, 0.0)]
            })
            .collect();
        let balanced = (n as f32 / LEAF_SIZE as f32).log2().ceil() as u32 + 1;
        for start in [0, SAH_DEPTH] {
            let root = build_in(&tris, start, 0, None);
            let d = depth(&root);
            if start == 0 {
                assert!(d > balanced + 4, "depth {d}: the heuristic did not chain, the test proves nothing");
                assert!(d <= SAH_DEPTH + (n as f32).log2().ceil() as u32 + 1, "depth {d}");
            } else {
                assert!(d <= balanced + 1, "middle splits: depth {d}, balanced {balanced}");
            }
            let mut runs = Vec::new();
            leaves(&root, &mut runs);
            assert!(runs.iter().all(|(ids, _)| (1..=LEAF_SIZE).contains(&ids.len())));
            let mut seen: Vec<u32> = runs.iter().flat_map(|(ids, _)| ids.to_vec()).collect();
            seen.sort_unstable();
            assert_eq!(seen, (0..n as u32).collect::<Vec<_>>(), "every triangle in exactly one leaf");
        }
    }

    /// Long walls around a grid of small triangles: object splits would leave the walls in boxes
    /// as large as the room, so spatial splits cut them. The copies stay within the budget, no
    /// leaf holds a triangle twice, every triangle is in some leaf, and every point of a wall is
    /// in the box of one of the leaves that hold it.
    #[test]
    fn spatial_splits_cut_long_walls_within_the_budget() {
        let mut tris = Vec::new();
        // Floor, ceiling and two walls, each of 16 strips (two triangles each) spanning the room.
        for k in 0..16 {
            let (z0, z1) = (k as f32 * 0.625, (k + 1) as f32 * 0.625);
            for y in [0.0, 10.0] {
                tris.push([Vec3::new(0.0, y, z0), Vec3::new(10.0, y, z0), Vec3::new(10.0, y, z1)]);
                tris.push([Vec3::new(0.0, y, z0), Vec3::new(10.0, y, z1), Vec3::new(0.0, y, z1)]);
            }
            for x in [0.0, 10.0] {
                tris.push([Vec3::new(x, 0.0, z0), Vec3::new(x, 10.0, z0), Vec3::new(x, 10.0, z1)]);
                tris.push([Vec3::new(x, 0.0, z0), Vec3::new(x, 10.0, z1), Vec3::new(x, 0.0, z1)]);
            }
        }
        let walls = tris.len();
        for i in 0..40 {
            for j in 0..40 {
                let p = Vec3::new(0.5 + i as f32 * 0.23, 5.0 + ((i * j) % 7) as f32 * 0.3, 0.5 + j as f32 * 0.23);
                tris.push([p, p + Vec3::new(0.1, 0.0, 0.0), p + Vec3::new(0.0, 0.1, 0.05)]);
            }
        }
        let budget = (DUPLICATES * tris.len() as f32) as usize;
        let root = build_in(&tris, 0, budget, None);
        let mut runs = Vec::new();
        leaves(&root, &mut runs);
        let references: usize = runs.iter().map(|(ids, _)| ids.len()).sum();
        assert!(references > tris.len(), "{references} references: no wall was cut");
        assert!(references <= tris.len() + budget, "{references} references exceed the budget");
        for (ids, _) in &runs {
            let mut sorted = ids.to_vec();
            sorted.sort_unstable();
            sorted.dedup();
            assert_eq!(sorted.len(), ids.len(), "a triangle twice in one leaf");
        }
        let mut seen: Vec<u32> = runs.iter().flat_map(|(ids, _)| ids.to_vec()).collect();
        seen.sort_unstable();
        seen.dedup();
        assert_eq!(seen.len(), tris.len(), "a triangle in no leaf");
        for (id, tri) in tris.iter().enumerate().take(walls) {
            let boxes: Vec<Aabb> = runs.iter().filter(|(ids, _)| ids.contains(&(id as u32))).map(|r| r.1).collect();
            for i in 0..=50 {
                for j in 0..=50 - i {
                    // The point in f64 (f32 arithmetic would put it off the wall's plane), kept in
                    // the triangle's box against the last bit of rounding.
                    let (u, v) = (i as f64 / 50.0, j as f64 / 50.0);
                    let p: [f64; 3] = core::array::from_fn(|a| {
                        let x = (1.0 - u - v) * tri[0][a] as f64 + u * tri[1][a] as f64 + v * tri[2][a] as f64;
                        let (lo, hi) =
                            (tri[0][a].min(tri[1][a]).min(tri[2][a]), tri[0][a].max(tri[1][a]).max(tri[2][a]));
                        x.clamp(lo as f64, hi as f64)
                    });
                    assert!(
                        boxes.iter().any(|b| (0..3).all(|a| b.lo[a] as f64 <= p[a] && p[a] <= b.hi[a] as f64)),
                        "wall {id}: point {p:?} in none of its {} leaves' boxes",
                        boxes.len()
                    );
                }
            }
        }
    }
}
