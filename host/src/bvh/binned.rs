//! The binary BVH the wide tree is collapsed from: top-down, split by the surface area
//! heuristic over 16 bins of the triangles' centroids per axis (Wald, "On fast Construction of
//! SAH-based Bounding Volume Hierarchies", RT 2007), the two halves built in parallel.
//!
//! A leaf holds at most `LEAF_SIZE` triangles, one block of the CPU's eight-lane test: a node with
//! more is always split, by the heuristic where it finds a split, else at the middle of its
//! centroids' order. Below `SAH_DEPTH` every split is that middle one, so the depth stays below
//! `SAH_DEPTH` + log2(n) whatever the geometry.
use shared::glam::Vec3;

/// Triangles a leaf may hold: a `TriBlock`.
pub const LEAF_SIZE: usize = shared::layout::BLOCK_WIDTH as usize;
const BINS: usize = 16;
/// Depth below which splits stop looking at the heuristic.
const SAH_DEPTH: u32 = 48;
/// Triangles below which a node's two halves are built on this thread.
const PARALLEL_MIN: usize = 4096;

/// A triangle's box and the centre of that box.
#[derive(Clone, Copy)]
pub struct Prim {
    pub lo: Vec3,
    pub hi: Vec3,
    pub centre: Vec3,
}

/// A box that grows: empty until something is added.
#[derive(Clone, Copy)]
pub struct Aabb {
    pub lo: Vec3,
    pub hi: Vec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb { lo: Vec3::splat(f32::INFINITY), hi: Vec3::splat(f32::NEG_INFINITY) };

    #[inline]
    pub fn grow(&mut self, lo: Vec3, hi: Vec3) {
        self.lo = self.lo.min(lo);
        self.hi = self.hi.max(hi);
    }

    /// Half the surface area; 0 for an empty box.
    #[inline]
    pub fn half_area(&self) -> f32 {
        let d = (self.hi - self.lo).max(Vec3::ZERO);
        d.x * d.y + d.y * d.z + d.z * d.x
    }
}

/// A node of the binary tree: its box, and either a run of the id list or two children.
pub struct Node2 {
    pub bounds: Aabb,
    pub kind: Kind,
}

pub enum Kind {
    Leaf { start: u32, count: u32 },
    Inner(Box<[Node2; 2]>),
}

/// Builds the tree over `ids` (a permutation of triangle ids, reordered in place so that every
/// leaf is a run of it); `start` is the position of `ids[0]` in the whole list.
pub fn build(prims: &[Prim], ids: &mut [u32], start: u32, depth: u32) -> Node2 {
    let mut bounds = Aabb::EMPTY;
    let mut centres = Aabb::EMPTY;
    for &id in ids.iter() {
        let p = &prims[id as usize];
        bounds.grow(p.lo, p.hi);
        centres.grow(p.centre, p.centre);
    }
    if ids.len() <= LEAF_SIZE {
        return Node2 { bounds, kind: Kind::Leaf { start, count: ids.len() as u32 } };
    }
    let mid = if depth < SAH_DEPTH { sah_split(prims, ids, &centres) } else { None };
    let mid = mid.unwrap_or_else(|| middle_split(prims, ids, &centres));
    let (left, right) = ids.split_at_mut(mid);
    let right_start = start + mid as u32;
    let (a, b) = if left.len() + right.len() >= PARALLEL_MIN {
        rayon::join(|| build(prims, left, start, depth + 1), || build(prims, right, right_start, depth + 1))
    } else {
        (build(prims, left, start, depth + 1), build(prims, right, right_start, depth + 1))
    };
    Node2 { bounds, kind: Kind::Inner(Box::new([a, b])) }
}

/// The heuristic's best split over the bins of each axis: partitions `ids` and returns the size
/// of the left part, or `None` when the centroids do not separate.
fn sah_split(prims: &[Prim], ids: &mut [u32], centres: &Aabb) -> Option<usize> {
    let extent = centres.hi - centres.lo;
    let mut best: Option<(f32, usize, usize)> = None; // (cost, axis, bins on the left)
    for axis in 0..3 {
        let (lo, ext) = (centres.lo[axis], extent[axis]);
        if !(ext > 0.0) {
            continue;
        }
        let scale = BINS as f32 / ext;
        let mut boxes = [Aabb::EMPTY; BINS];
        let mut counts = [0usize; BINS];
        for &id in ids.iter() {
            let p = &prims[id as usize];
            let b = (((p.centre[axis] - lo) * scale) as usize).min(BINS - 1);
            boxes[b].grow(p.lo, p.hi);
            counts[b] += 1;
        }
        // Sweep from the right, then from the left: cost = A_L·N_L + A_R·N_R.
        let mut right_area = [0.0f32; BINS];
        let mut acc = Aabb::EMPTY;
        for b in (1..BINS).rev() {
            acc.grow(boxes[b].lo, boxes[b].hi);
            right_area[b] = acc.half_area();
        }
        let mut left = Aabb::EMPTY;
        let mut n_left = 0usize;
        for b in 0..BINS - 1 {
            left.grow(boxes[b].lo, boxes[b].hi);
            n_left += counts[b];
            let n_right = ids.len() - n_left;
            if n_left == 0 || n_right == 0 {
                continue;
            }
            let cost = left.half_area() * n_left as f32 + right_area[b + 1] * n_right as f32;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b + 1));
            }
        }
    }
    let (_, axis, split_bin) = best?;
    let (lo, scale) = (centres.lo[axis], BINS as f32 / extent[axis]);
    let left_of = |id: u32| (((prims[id as usize].centre[axis] - lo) * scale) as usize).min(BINS - 1) < split_bin;
    // In-place partition.
    let (mut i, mut j) = (0usize, ids.len());
    while i < j {
        if left_of(ids[i]) {
            i += 1;
        } else {
            j -= 1;
            ids.swap(i, j);
        }
    }
    (i > 0 && i < ids.len()).then_some(i)
}

/// Splits at the middle of the centroids' order along the widest axis (ties by id, so the
/// tree does not depend on the input order's accidents).
fn middle_split(prims: &[Prim], ids: &mut [u32], centres: &Aabb) -> usize {
    let extent = centres.hi - centres.lo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = ids.len() / 2;
    ids.select_nth_unstable_by(mid, |&a, &b| {
        let (ca, cb) = (prims[a as usize].centre[axis], prims[b as usize].centre[axis]);
        ca.total_cmp(&cb).then(a.cmp(&b))
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

    fn leaves(n: &Node2, out: &mut Vec<(u32, u32)>) {
        match &n.kind {
            Kind::Leaf { start, count } => out.push((*start, *count)),
            Kind::Inner(kids) => kids.iter().for_each(|k| leaves(k, out)),
        }
    }

    /// Triangles at exponentially growing distances: the best SAH plane peels the few farthest
    /// off at each split, a chain far deeper than a balanced tree, yet within the bound; past
    /// `SAH_DEPTH` (the build entered there) the middle splits are balanced. Every triangle lands
    /// in exactly one leaf of at most `LEAF_SIZE`.
    #[test]
    fn a_chain_of_peeled_triangles_stays_within_the_depth_bound() {
        let n = 300usize;
        let prims: Vec<Prim> = (0..n)
            .map(|i| {
                let x = 1.3f32.powi(i as i32);
                let (lo, hi) = (Vec3::new(x, 0.0, 0.0), Vec3::new(x * 1.001, 1.0, 0.0));
                Prim { lo, hi, centre: (lo + hi) * 0.5 }
            })
            .collect();
        let balanced = (n as f32 / LEAF_SIZE as f32).log2().ceil() as u32 + 1;
        for start in [0, SAH_DEPTH] {
            let mut ids: Vec<u32> = (0..n as u32).collect();
            let root = build(&prims, &mut ids, 0, start);
            let d = depth(&root);
            if start == 0 {
                assert!(d > balanced + 4, "depth {d}: the heuristic did not chain, the test proves nothing");
                assert!(d <= SAH_DEPTH + (n as f32).log2().ceil() as u32 + 1, "depth {d}");
            } else {
                assert!(d <= balanced + 1, "middle splits: depth {d}, balanced {balanced}");
            }
            let mut runs = Vec::new();
            leaves(&root, &mut runs);
            assert!(runs.iter().all(|&(_, c)| (1..=LEAF_SIZE as u32).contains(&c)));
            let mut seen: Vec<u32> =
                runs.iter().flat_map(|&(s, c)| ids[s as usize..(s + c) as usize].to_vec()).collect();
            seen.sort_unstable();
            assert_eq!(seen, (0..n as u32).collect::<Vec<_>>(), "every triangle in exactly one leaf");
        }
    }
}
