//! Spatial splits for the binary BVH (Stich, Friedrich & Dietrich, "Spatial Splits in Bounding
//! Volume Hierarchies", HPG 2009): where the best split of a node's triangles leaves the two
//! children's boxes overlapping, a plane may instead cut the triangles that straddle it, each
//! part going to its side with the box of the part only. Long triangles that span a room (a
//! floor, a wall) then stop inflating every box they are in.
//!
//! A triangle cut in two is in two leaves, so a ray may test it twice: the traversal keeps the
//! closer hit and, at equal distance, the lower id, so the answer is unchanged. Each part's box
//! must hold all of the triangle on its side, or a ray could pass the triangle by: the plane is
//! exact, and the points where edges cross it are widened by more than their rounding error.
use super::reference::{Aabb, Ref};
use shared::glam::Vec3;

/// Planes tried per axis: the bins' borders.
pub const BINS: usize = 16;

/// A split plane `axis = plane` and its heuristic cost (A_L·N_L + A_R·N_R, half areas).
#[derive(Clone, Copy, Debug)]
pub struct SpatialSplit {
    pub cost: f32,
    pub axis: usize,
    pub plane: f32,
}

/// Cuts the part of triangle `tri` inside `r` at `axis = plane`: the boxes of the part on each
/// side (closed: a point on the plane is on both), each within `r`; `Aabb::EMPTY` for a side the
/// part does not reach.
pub fn split_ref(tri: &[Vec3; 3], r: &Aabb, axis: usize, plane: f32) -> (Aabb, Aabb) {
    let (mut left, mut right) = (Aabb::EMPTY, Aabb::EMPTY);
    for i in 0..3 {
        let (a, b) = (tri[i], tri[(i + 1) % 3]);
        if a[axis] <= plane {
            left.grow(a, a);
        }
        if a[axis] >= plane {
            right.grow(a, a);
        }
        if (a[axis] < plane && plane < b[axis]) || (b[axis] < plane && plane < a[axis]) {
            let t = (plane - a[axis]) / (b[axis] - a[axis]);
            let mut x = a + (b - a) * t;
            // The crossing carries a few ulps of the edge's coordinates; eight ulps and the
            // smallest normal number cover it (t in [0, 1] and two roundings per component), and
            // on the split axis it is the plane.
            // Where both ends share a coordinate the crossing has it exactly: a wall's boxes stay
            // flat.
            let pad = a.abs().max(b.abs()) * (8.0 * f32::EPSILON) + Vec3::splat(f32::MIN_POSITIVE);
            let pad = Vec3::select(a.cmpeq(b), Vec3::ZERO, pad);
            x[axis] = plane;
            left.grow(x - pad, x + pad);
            right.grow(x - pad, x + pad);
        }
    }
    left.hi[axis] = left.hi[axis].min(plane);
    right.lo[axis] = right.lo[axis].max(plane);
    (left.intersect(r), right.intersect(r))
}

/// The best spatial split of `refs` (boxes `bounds`) that duplicates at most `budget` references,
/// if any separates them; with `parallel`, the three axes at once.
pub fn find(tris: &[[Vec3; 3]], refs: &[Ref], bounds: &Aabb, budget: usize, parallel: bool) -> Option<SpatialSplit> {
    let per_axis = |axis: usize| find_on(tris, refs, bounds, budget, axis);
    let best = if parallel {
        use rayon::prelude::*;
        (0..3).into_par_iter().map(per_axis).collect::<Vec<_>>()
    } else {
        (0..3).map(per_axis).collect()
    };
    best.into_iter().flatten().reduce(|a, b| if b.cost < a.cost { b } else { a })
}

/// The best spatial split on one axis.
fn find_on(tris: &[[Vec3; 3]], refs: &[Ref], bounds: &Aabb, budget: usize, axis: usize) -> Option<SpatialSplit> {
    let n = refs.len();
    let (lo, ext) = (bounds.lo[axis], bounds.hi[axis] - bounds.lo[axis]);
    if !(ext > 0.0) {
        return None;
    }
    let width = ext / BINS as f32;
    let plane = |i: usize| lo + width * i as f32;
    let bin_of = |x: f32| (((x - lo) / width) as usize).min(BINS - 1);
    let mut boxes = [Aabb::EMPTY; BINS];
    let (mut entries, mut exits) = ([0usize; BINS], [0usize; BINS]);
    for r in refs {
        let (b0, b1) = (bin_of(r.b.lo[axis]), bin_of(r.b.hi[axis]));
        entries[b0] += 1;
        exits[b1] += 1;
        let mut rest = r.b;
        for (b, bin) in boxes.iter_mut().enumerate().take(b1).skip(b0) {
            let (part, next) = split_ref(&tris[r.id as usize], &rest, axis, plane(b + 1));
            bin.grow(part.lo, part.hi);
            rest = next;
        }
        boxes[b1].grow(rest.lo, rest.hi);
    }
    // Sweep: right-hand areas and counts first, then the left side plane by plane.
    let mut right_area = [0.0f32; BINS];
    let mut right_count = [0usize; BINS];
    let (mut acc, mut count) = (Aabb::EMPTY, 0usize);
    for b in (1..BINS).rev() {
        acc.grow(boxes[b].lo, boxes[b].hi);
        count += exits[b];
        right_area[b] = acc.half_area();
        right_count[b] = count;
    }
    let mut best: Option<SpatialSplit> = None;
    let (mut left, mut n_left) = (Aabb::EMPTY, 0usize);
    for b in 0..BINS - 1 {
        left.grow(boxes[b].lo, boxes[b].hi);
        n_left += entries[b];
        let n_right = right_count[b + 1];
        if n_left == 0 || n_right == 0 || n_left == n || n_right == n || n_left + n_right - n > budget {
            continue;
        }
        let cost = left.half_area() * n_left as f32 + right_area[b + 1] * n_right as f32;
        if best.is_none_or(|s| cost < s.cost) {
            best = Some(SpatialSplit { cost, axis, plane: plane(b + 1) });
        }
    }
    best
}

/// Sends each reference to the side of the plane it lies on, cutting those that straddle it.
pub fn partition(tris: &[[Vec3; 3]], refs: &[Ref], s: SpatialSplit) -> (Vec<Ref>, Vec<Ref>) {
    let (mut left, mut right) = (Vec::with_capacity(refs.len()), Vec::with_capacity(refs.len()));
    for &r in refs {
        if r.b.hi[s.axis] <= s.plane {
            left.push(r);
        } else if r.b.lo[s.axis] >= s.plane {
            right.push(r);
        } else {
            let (l, h) = split_ref(&tris[r.id as usize], &r.b, s.axis, s.plane);
            if !l.is_empty() {
                left.push(Ref { id: r.id, b: l });
            }
            if !h.is_empty() {
                right.push(Ref { id: r.id, b: h });
            }
        }
    }
    (left, right)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Cut at many planes, the two parts' boxes hold every point of the triangle on their side,
    /// sampled densely, edges and corners included: no ray can pass the triangle by.
    #[test]
    fn the_parts_hold_the_triangle() {
        let tris = [
            [Vec3::new(-3.7, 0.1, 2.0), Vec3::new(5.3, 1.9, -1.1), Vec3::new(0.2, -4.4, 0.7)],
            [Vec3::new(1e4, 1e4 + 1.0, 3.0), Vec3::new(1e4 + 7.0, 1e4 - 2.0, 3.5), Vec3::new(1e4 - 5.0, 1e4, 2.0)],
            [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1e-3, 2e-3, 0.0), Vec3::new(0.0, 1e-3, 1e-7)],
        ];
        let mut parts = 0;
        for tri in &tris {
            let mut whole = Aabb::EMPTY;
            tri.iter().for_each(|&v| whole.grow(v, v));
            for axis in 0..3 {
                for k in 1..32 {
                    let plane = whole.lo[axis] + (whole.hi[axis] - whole.lo[axis]) * (k as f32 / 32.0);
                    let (l, r) = split_ref(tri, &whole, axis, plane);
                    assert!(l.hi[axis] <= plane && r.lo[axis] >= plane);
                    for i in 0..=64 {
                        for j in 0..=64 - i {
                            let (u, v) = (i as f64 / 64.0, j as f64 / 64.0);
                            let p: [f64; 3] = core::array::from_fn(|a| {
                                (1.0 - u - v) * tri[0][a] as f64 + u * tri[1][a] as f64 + v * tri[2][a] as f64
                            });
                            let inside = |b: &Aabb| (0..3).all(|a| b.lo[a] as f64 <= p[a] && p[a] <= b.hi[a] as f64);
                            let side_ok = if p[axis] < plane as f64 {
                                inside(&l)
                            } else if p[axis] > plane as f64 {
                                inside(&r)
                            } else {
                                inside(&l) && inside(&r)
                            };
                            assert!(side_ok, "point {p:?} of {tri:?} cut at {axis}={plane}: left {l:?} right {r:?}");
                            parts += 1;
                        }
                    }
                }
            }
        }
        assert!(parts > 100_000);
    }

    /// A part's box is within the reference's box, and tighter than it where the cut helps.
    #[test]
    fn the_parts_stay_in_the_reference() {
        let tri = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(10.0, 0.0, 0.0), Vec3::new(0.0, 10.0, 0.0)];
        let r = Aabb { lo: Vec3::new(0.0, 0.0, -1.0), hi: Vec3::new(6.0, 10.0, 1.0) };
        let (l, h) = split_ref(&tri, &r, 0, 5.0);
        assert_eq!((l.lo.x, l.hi.x, l.hi.y), (0.0, 5.0, 10.0));
        assert_eq!((h.lo.x, h.hi.x), (5.0, 6.0));
        // Right of x = 5 the triangle reaches y = 5 only.
        assert!(h.hi.y < 5.001 && h.hi.y >= 5.0, "{h:?}");
        assert_eq!((l.lo.z, l.hi.z), (0.0, 0.0));
    }
}
