//! The spatial-median k-d tree builder: splits at the middle of the node's longest axis. A
//! baseline for the SAH builder's benchmarks, not the default.
//!
//! It writes the final node layout (`shared::layout::KdNode`: below child adjacent, leaves as
//! runs in one index list) that the traversal in `shared::kdtree` reads. Triangles are placed by
//! their bounding boxes: a triangle goes to every child whose closed half-space its box reaches
//! beyond the plane, and one lying in the plane goes to both. That placement is conservative, so
//! traversal returns exactly the brute-force hit.
use super::KdTree;
use shared::glam::Vec3;
use shared::layout::{KdNode, Triangle};
use shared::vecmath::{axis, xyz};

#[derive(Clone, Copy)]
struct Aabb {
    lo: Vec3,
    hi: Vec3,
}

fn triangle_box(t: &Triangle) -> Aabb {
    let (a, b, c) = (xyz(t.v0), xyz(t.v1), xyz(t.v2));
    Aabb { lo: a.min(b).min(c), hi: a.max(b).max(c) }
}

/// Which children a box goes to for a split at `s` on `a`: (below, above).
fn sides(b: &Aabb, a: u32, s: f32) -> (bool, bool) {
    let (lo, hi) = (axis(b.lo, a), axis(b.hi, a));
    let planar = (lo == s) & (hi == s);
    (lo < s || planar, hi > s || planar)
}

/// Builds with spatial-median splits; nodes of at most `leaf_size` triangles become leaves.
pub fn build(triangles: &[Triangle], bounds_min: Vec3, bounds_max: Vec3, leaf_size: u32, max_depth: u32) -> KdTree {
    let boxes: Vec<Aabb> = triangles.iter().map(triangle_box).collect();
    let mut tree = KdTree { bounds_min, bounds_max, ..Default::default() };
    let ids: Vec<u32> = (0..triangles.len() as u32).collect();
    let mut builder = Builder { boxes: &boxes, max_depth, leaf_size: leaf_size.max(1), tree: &mut tree };
    builder.node(ids, Aabb { lo: bounds_min, hi: bounds_max }, 0);
    tree
}

struct Builder<'a> {
    boxes: &'a [Aabb],
    max_depth: u32,
    leaf_size: u32,
    tree: &'a mut KdTree,
}

impl Builder<'_> {
    fn leaf(&mut self, ids: &[u32]) {
        self.tree.nodes.push(KdNode::leaf(self.tree.indices.len() as u32, ids.len() as u32));
        self.tree.indices.extend_from_slice(ids);
    }

    fn node(&mut self, ids: Vec<u32>, bounds: Aabb, depth: u32) {
        self.tree.depth = self.tree.depth.max(depth);
        if ids.len() as u32 <= self.leaf_size || depth >= self.max_depth {
            return self.leaf(&ids);
        }
        let extent = bounds.hi - bounds.lo;
        let mut axes = [0u32, 1, 2];
        axes.sort_by(|&a, &b| axis(extent, b).total_cmp(&axis(extent, a)));
        for a in axes {
            let s = 0.5 * (axis(bounds.lo, a) + axis(bounds.hi, a));
            if !(s > axis(bounds.lo, a) && s < axis(bounds.hi, a)) {
                continue;
            }
            let (mut below, mut above) = (Vec::new(), Vec::new());
            for &id in &ids {
                let (b, t) = sides(&self.boxes[id as usize], a, s);
                if b {
                    below.push(id);
                }
                if t {
                    above.push(id);
                }
            }
            // A split that leaves (almost) every triangle on both sides only adds depth.
            if below.len() + above.len() > ids.len() + ids.len() / 2
                || below.len() == ids.len() && above.len() == ids.len()
            {
                continue;
            }
            let me = self.tree.nodes.len();
            self.tree.nodes.push(KdNode::default());
            let mut below_box = bounds;
            let mut above_box = bounds;
            set_axis(&mut below_box.hi, a, s);
            set_axis(&mut above_box.lo, a, s);
            drop(ids);
            self.node(below, below_box, depth + 1);
            let above_index = self.tree.nodes.len() as u32;
            self.tree.nodes[me] = KdNode::interior(a, s, above_index);
            self.node(above, above_box, depth + 1);
            return;
        }
        self.leaf(&ids)
    }
}

fn set_axis(v: &mut Vec3, a: u32, x: f32) {
    match a {
        0 => v.x = x,
        1 => v.y = x,
        _ => v.z = x,
    }
}
