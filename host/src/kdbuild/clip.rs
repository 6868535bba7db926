//! Perfect splits: the part of a triangle inside a voxel, and its bounding box.
//!
//! Havran's thesis (2000, §4.5) and Wald & Havran 2006 (§4.3, "perfect splits"): a triangle that
//! straddles a split plane is clipped to each child's voxel and its events are made from the
//! clipped polygon's bounding box, not from the triangle's. The box is smaller, so fewer
//! triangles are referenced by leaves they only touch with their bounding box.
//!
//! Clipping runs in f64 (Sutherland–Hodgman against the six planes of the closed box) and the
//! box is rounded outward to f32 and then clamped to the voxel, so it always contains the part
//! of the triangle inside the voxel: a leaf never loses a triangle it really overlaps.
use shared::layout::Triangle;
use shared::numerics::{next_float_down, next_float_up};

/// An axis-aligned box in f32, closed: `lo <= hi` on every axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub lo: [f32; 3],
    pub hi: [f32; 3],
}

impl Aabb {
    pub fn extent(&self, k: usize) -> f64 {
        self.hi[k] as f64 - self.lo[k] as f64
    }

    /// Surface area, in f64 so that thin voxels of huge scenes keep their ratios.
    pub fn area(&self) -> f64 {
        let (x, y, z) = (self.extent(0), self.extent(1), self.extent(2));
        2.0 * (x * y + y * z + z * x)
    }

    /// The two halves of a split at `pos` on axis `k`: (below, above).
    pub fn split(&self, k: usize, pos: f32) -> (Aabb, Aabb) {
        let (mut below, mut above) = (*self, *self);
        below.hi[k] = pos;
        above.lo[k] = pos;
        (below, above)
    }
}

/// The smaller of two numbers that are not NaN (scenes reject non-finite vertices, and clipping
/// interpolates between finite ones): one comparison, where `f64::min` also handles NaN, and
/// clipping straddlers runs at every split.
#[inline]
fn lesser<T: PartialOrd>(a: T, b: T) -> T {
    if b < a {
        b
    } else {
        a
    }
}

/// The larger of two numbers that are not NaN (`lesser`).
#[inline]
fn greater<T: PartialOrd>(a: T, b: T) -> T {
    if b > a {
        b
    } else {
        a
    }
}

/// A triangle's vertices in f64.
pub type Tri64 = [[f64; 3]; 3];

pub fn to_f64(t: &Triangle) -> Tri64 {
    [
        [t.v0.x as f64, t.v0.y as f64, t.v0.z as f64],
        [t.v1.x as f64, t.v1.y as f64, t.v1.z as f64],
        [t.v2.x as f64, t.v2.y as f64, t.v2.z as f64],
    ]
}

/// Room for the clipped polygon: a convex triangle gains at most one vertex per plane (9 in
/// all); rounding can make a near-degenerate polygon slightly non-convex, so leave spare room
/// and fall back to no clipping (still conservative) if even that is exceeded.
const MAX_VERTICES: usize = 16;

/// A convex polygon of at most `MAX_VERTICES` vertices.
#[derive(Clone, Copy)]
pub struct Polygon {
    pub v: [[f64; 3]; MAX_VERTICES],
    pub len: usize,
}

impl Polygon {
    pub fn vertices(&self) -> &[[f64; 3]] {
        &self.v[..self.len]
    }

    /// (min, max) of the vertices on axis `k`; only for a non-empty polygon.
    pub fn range(&self, k: usize) -> (f64, f64) {
        self.vertices()
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lesser(lo, p[k]), greater(hi, p[k])))
    }
}

/// Keeps the part of `input` with `x[k] >= bound` (`above`) or `x[k] <= bound`. Returns false if
/// the output would overflow.
fn clip_plane(input: &Polygon, out: &mut Polygon, k: usize, bound: f64, above: bool) -> bool {
    let src = input.vertices();
    let inside = |p: &[f64; 3]| if above { p[k] >= bound } else { p[k] <= bound };
    // The count stays in a register and each vertex's side is tested once: this loop runs for
    // every straddling triangle of every split.
    let mut m = 0;
    let Some(first) = src.first() else {
        out.len = 0;
        return true;
    };
    let mut ia = inside(first);
    for (i, a) in src.iter().enumerate() {
        let b = if i + 1 == src.len() { first } else { &src[i + 1] };
        let ib = inside(b);
        if ia {
            if m == MAX_VERTICES {
                return false;
            }
            out.v[m] = *a;
            m += 1;
        }
        if ia != ib {
            let t = (bound - a[k]) / (b[k] - a[k]);
            let mut p = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])];
            // The crossing lies on the plane by construction; make it exact.
            p[k] = bound;
            if m == MAX_VERTICES {
                return false;
            }
            out.v[m] = p;
            m += 1;
        }
        ia = ib;
    }
    out.len = m;
    true
}

/// Two polygons that clipping alternates between. A builder keeps one pair for all its clips:
/// a polygon is 400 bytes, and making and copying fresh ones cost more than clipping the few
/// vertices a triangle has.
#[derive(Clone, Copy)]
pub struct ClipBuffers([Polygon; 2]);

impl Default for ClipBuffers {
    fn default() -> Self {
        Self([Polygon { v: [[0.0; 3]; MAX_VERTICES], len: 0 }; 2])
    }
}

/// Clips into `bufs` and returns which of the two holds the result, or `None` on overflow.
fn clip_into(t: &Tri64, b: &Aabb, bufs: &mut ClipBuffers) -> Option<usize> {
    let [first, second] = &mut bufs.0;
    first.v[..3].copy_from_slice(t);
    first.len = 3;
    let mut cur = 0;
    for k in 0..3 {
        for (bound, above) in [(b.lo[k] as f64, true), (b.hi[k] as f64, false)] {
            let (from, to) = if cur == 0 { (&*first, &mut *second) } else { (&*second, &mut *first) };
            // Most planes cut nothing (a child voxel differs from its parent by one plane).
            if from.vertices().iter().all(|p| if above { p[k] >= bound } else { p[k] <= bound }) {
                continue;
            }
            if !clip_plane(from, to, k, bound, above) {
                return None;
            }
            cur ^= 1;
            if to.len == 0 {
                return Some(cur);
            }
        }
    }
    Some(cur)
}

/// The part of the triangle inside the closed box, or `None` if clipping overflowed (never for
/// a proper triangle; the caller then falls back to the unclipped box). An empty polygon
/// (`len == 0`) means the triangle misses the box.
pub fn clip_polygon(t: &Tri64, b: &Aabb) -> Option<Polygon> {
    let mut bufs = ClipBuffers::default();
    clip_into(t, b, &mut bufs).map(|i| bufs.0[i])
}

/// Largest f32 not above `x`.
fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x {
        next_float_down(f)
    } else {
        f
    }
}

/// Smallest f32 not below `x`.
fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x {
        next_float_up(f)
    } else {
        f
    }
}

/// The bounding box of the triangle's part inside `voxel`, rounded outward to f32 and clamped
/// to the voxel; `None` when the triangle misses the voxel.
pub fn clipped_box(t: &Tri64, voxel: &Aabb) -> Option<Aabb> {
    clipped_box_with(t, voxel, &mut ClipBuffers::default())
}

/// `clipped_box` with the caller's clipping buffers.
pub fn clipped_box_with(t: &Tri64, voxel: &Aabb, bufs: &mut ClipBuffers) -> Option<Aabb> {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in t {
        for k in 0..3 {
            lo[k] = lesser(lo[k], p[k]);
            hi[k] = greater(hi[k], p[k]);
        }
    }
    let inside = (0..3).all(|k| lo[k] >= voxel.lo[k] as f64 && hi[k] <= voxel.hi[k] as f64);
    if !inside {
        if let Some(i) = clip_into(t, voxel, bufs) {
            let poly = &bufs.0[i];
            if poly.len == 0 {
                return None;
            }
            for k in 0..3 {
                (lo[k], hi[k]) = poly.range(k);
            }
        }
        // On overflow the triangle's own box stands in: larger, still conservative.
    }
    rounded_box(&lo, &hi, voxel)
}

/// The f64 box `lo`..`hi` rounded outward to f32 and clamped to `voxel`; `None` when nothing of
/// it is left in the voxel.
fn rounded_box(lo: &[f64; 3], hi: &[f64; 3], voxel: &Aabb) -> Option<Aabb> {
    let mut out = Aabb { lo: [0.0; 3], hi: [0.0; 3] };
    for k in 0..3 {
        out.lo[k] = greater(round_down(lo[k]), voxel.lo[k]);
        out.hi[k] = lesser(round_up(hi[k]), voxel.hi[k]);
        if out.lo[k] > out.hi[k] {
            return None;
        }
    }
    Some(out)
}

/// The boxes `clipped_box_with` gives the triangle in the two halves of `voxel` split at `pos`
/// on axis `k` (below, above), from one clip: the triangle is clipped to the voxel once (not
/// at all when it lies inside it), and the polygon is then cut at the plane in one pass that
/// keeps each side's bounds, where clipping to each half clipped against up to six planes
/// twice. A crossing of the plane is computed as `clip_plane` computes it, along the same
/// edge, so both halves share it. `None` when the clip to the voxel overflows or leaves
/// nothing; the caller then clips to each half.
pub fn split_boxes(t: &Tri64, voxel: &Aabb, k: usize, pos: f32, bufs: &mut ClipBuffers) -> Option<[Option<Aabb>; 2]> {
    let inside = (0..3).all(|j| t.iter().all(|p| p[j] >= voxel.lo[j] as f64 && p[j] <= voxel.hi[j] as f64));
    let poly = if inside {
        let first = &mut bufs.0[0];
        first.v[..3].copy_from_slice(t);
        first.len = 3;
        &bufs.0[0]
    } else {
        &bufs.0[clip_into(t, voxel, bufs)?]
    };
    let src = poly.vertices();
    if src.is_empty() {
        return None;
    }
    let plane = pos as f64;
    let (mut lo, mut hi) = ([[f64::INFINITY; 3]; 2], [[f64::NEG_INFINITY; 3]; 2]);
    let mut take = |side: usize, p: &[f64; 3]| {
        for j in 0..3 {
            lo[side][j] = lesser(lo[side][j], p[j]);
            hi[side][j] = greater(hi[side][j], p[j]);
        }
    };
    for (i, a) in src.iter().enumerate() {
        let b = src.get(i + 1).unwrap_or(&src[0]);
        if a[k] <= plane {
            take(0, a);
        }
        if a[k] >= plane {
            take(1, a);
        }
        if (a[k] < plane && b[k] > plane) || (a[k] > plane && b[k] < plane) {
            let t = (plane - a[k]) / (b[k] - a[k]);
            let mut p = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])];
            p[k] = plane;
            take(0, &p);
            take(1, &p);
        }
    }
    let (below, above) = voxel.split(k, pos);
    let mut boxes = [None; 2];
    for (side, half) in [below, above].iter().enumerate() {
        // A side that took no point is missed.
        if lo[side][0] <= hi[side][0] {
            boxes[side] = rounded_box(&lo[side], &hi[side], half);
        }
    }
    Some(boxes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit() -> Aabb {
        Aabb { lo: [0.0; 3], hi: [1.0; 3] }
    }

    #[test]
    fn inside_triangle_keeps_its_box() {
        let f = |x: f32| x as f64;
        let t = [[f(0.1), f(0.2), f(0.3)], [f(0.9), f(0.2), f(0.3)], [f(0.5), f(0.8), f(0.3)]];
        let b = clipped_box(&t, &unit()).unwrap();
        assert_eq!(b.lo, [0.1, 0.2, 0.3]);
        assert_eq!(b.hi, [0.9, 0.8, 0.3]);
    }

    #[test]
    fn straddling_triangle_is_clipped_tighter_than_its_box() {
        // A long sliver along x + y = 0.5 across the corner of the unit box: its own box covers
        // the whole unit square, the part inside only the corner below that line.
        let t = [[-1.0, 1.5, 0.5], [1.5, -1.0, 0.5], [1.5, -0.9, 0.5]];
        let b = clipped_box(&t, &unit()).unwrap();
        assert!(b.lo[0] == 0.0 && b.lo[1] == 0.0 && b.hi[0] < 0.6 && b.hi[1] < 0.6, "{b:?}");
        assert_eq!((b.lo[2], b.hi[2]), (0.5, 0.5));
    }

    #[test]
    fn missing_triangle_is_none() {
        // Its box overlaps the voxel but the triangle passes beside the corner.
        let t = [[1.2, -0.5, 0.5], [1.5, 0.5, 0.5], [-0.5, 1.5, 0.5]];
        let (lo, hi) = ([0.0, 0.0, 0.0], [0.3, 0.3, 1.0]);
        assert!(clipped_box(&t, &Aabb { lo, hi }).is_none());
    }

    #[test]
    fn triangle_on_a_face_is_kept() {
        let t = [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let b = clipped_box(&t, &Aabb { lo: [0.0, 0.2, 0.2], hi: [1.0, 0.4, 0.4] }).unwrap();
        assert_eq!((b.lo[0], b.hi[0]), (0.0, 0.0));
    }

    #[test]
    fn clipped_box_contains_the_exact_part() {
        // Points of the triangle inside the voxel must lie in the clipped box.
        let t = [[-0.31, 0.17, 0.4], [1.73, 0.49, 0.81], [0.22, 1.9, -0.6]];
        let v = Aabb { lo: [0.1, 0.1, 0.1], hi: [0.9, 0.8, 0.7] };
        let b = clipped_box(&t, &v).unwrap();
        let n = 300;
        for i in 0..=n {
            for j in 0..=(n - i) {
                let (u, w) = (i as f64 / n as f64, j as f64 / n as f64);
                let p: Vec<f64> = (0..3).map(|k| t[0][k] * (1.0 - u - w) + t[1][k] * u + t[2][k] * w).collect();
                let inside = (0..3).all(|k| p[k] >= v.lo[k] as f64 && p[k] <= v.hi[k] as f64);
                if inside {
                    assert!((0..3).all(|k| p[k] >= b.lo[k] as f64 && p[k] <= b.hi[k] as f64), "{p:?} outside {b:?}");
                }
            }
        }
    }

    /// Splitting the voxel's polygon at a plane gives the boxes that clipping to each half
    /// gives: the same but for a rounding of a crossing computed in another order (an f32 ulp
    /// at most, and rarely), and the same sides missed. Random triangles and planes, with
    /// vertices on the plane, on the voxel's faces and far outside it.
    #[test]
    fn split_boxes_agree_with_clipping_to_each_half() {
        let mut next = crate::kdbuild::xorshift(0x9e37_79b9_7f4a_7c15);
        let mut coordinate = || match next() % 8 {
            0 => 0.0,
            1 => 1.0,
            2 => 0.5,
            _ => (next() % 4001) as f64 / 1000.0 - 1.5,
        };
        let (mut compared, mut exact) = (0, 0);
        let mut bufs = ClipBuffers::default();
        let ulp = |a: f32, b: f32| (a.to_bits() as i64 - b.to_bits() as i64).abs();
        for trial in 0..20000 {
            let t: Tri64 = [(); 3].map(|_| [(); 3].map(|_| (coordinate() as f32) as f64));
            let k = trial % 3;
            let pos = [0.5f32, 0.25, 0.0, 1.0, std::f32::consts::FRAC_1_SQRT_2][trial % 5];
            let voxel = unit();
            let Some(split) = split_boxes(&t, &voxel, k, pos, &mut bufs) else { continue };
            let (below, above) = voxel.split(k, pos);
            for (got, half) in split.iter().zip([below, above]) {
                let want = clipped_box(&t, &half);
                assert_eq!(
                    got.is_some(),
                    want.is_some(),
                    "trial {trial}: {t:?} at {pos} on axis {k}: {got:?} against {want:?}"
                );
                if let (Some(g), Some(w)) = (got, want) {
                    let worst = (0..3).map(|j| ulp(g.lo[j], w.lo[j]).max(ulp(g.hi[j], w.hi[j]))).max().unwrap();
                    assert!(worst <= 1, "trial {trial}: {t:?} at {pos} on axis {k}: {g:?} against {w:?}");
                    compared += 1;
                    exact += (worst == 0) as usize;
                }
            }
        }
        assert!(compared > 5000, "only {compared} boxes compared");
        assert!(exact * 100 >= compared * 99, "only {exact} of {compared} boxes the same");
    }
}
