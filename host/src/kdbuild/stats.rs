//! What a built tree looks like: node and reference counts, depth, and its SAH cost
//! (Σ interior K_T·A(node)/A(root) + Σ leaves K_I·N·A(leaf)/A(root), MacDonald & Booth 1990):
//! the expected cost of a random ray through the root box, the number the builder minimises.
use super::clip::Aabb;
use super::{BuildSettings, KdTree};
use serde::Serialize;

#[derive(Clone, Debug, Default, Serialize)]
pub struct TreeStats {
    pub triangles: usize,
    pub nodes: usize,
    pub leaves: usize,
    pub empty_leaves: usize,
    pub max_depth: u32,
    /// Triangle references per non-empty leaf.
    pub mean_leaf_refs: f64,
    pub total_refs: usize,
    pub sah_cost: f64,
}

pub fn stats(tree: &KdTree, triangles: usize, settings: &BuildSettings) -> TreeStats {
    let mut s = TreeStats { triangles, nodes: tree.nodes.len(), ..Default::default() };
    let root = Aabb { lo: tree.bounds_min.to_array(), hi: tree.bounds_max.to_array() };
    let root_area = root.area();
    let mut cost = 0.0f64;
    let mut stack = vec![(0usize, root, 0u32)];
    while let Some((i, voxel, depth)) = stack.pop() {
        let Some(&n) = tree.nodes.get(i) else { continue };
        let share = if root_area > 0.0 { voxel.area() / root_area } else { 1.0 };
        s.max_depth = s.max_depth.max(depth);
        if n.is_leaf() {
            s.leaves += 1;
            let count = n.count() as usize;
            s.total_refs += count;
            s.empty_leaves += (count == 0) as usize;
            cost += settings.intersection_cost as f64 * settings.leaf_tests(count) as f64 * share;
        } else {
            cost += settings.traversal_cost as f64 * share;
            let (below, above) = voxel.split(n.axis() as usize, n.split());
            stack.push((i + 1, below, depth + 1));
            stack.push((n.above_child() as usize, above, depth + 1));
        }
    }
    let full = s.leaves - s.empty_leaves;
    s.mean_leaf_refs = if full > 0 { s.total_refs as f64 / full as f64 } else { 0.0 };
    s.sah_cost = cost;
    s
}
