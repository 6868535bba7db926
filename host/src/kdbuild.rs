//! A simple k-d tree builder: spatial-median splits on the longest axis of the node's box.
//!
//! It writes the final node layout (`shared::layout::KdNode`: below child adjacent, leaves as
//! runs in one index list) that the traversal in `shared::kdtree` reads. Triangles are placed by
//! their bounding boxes: a triangle goes to every child whose closed half-space its box reaches
//! beyond the plane, and one lying in the plane goes to both. That placement is conservative, so
//! traversal returns exactly the brute-force hit.
use shared::glam::Vec3;
use shared::layout::{KdNode, Triangle, KD_MAX_DEPTH};
use shared::vecmath::{axis, xyz};

#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
pub struct BuildSettings {
    /// Maximum depth; 0 picks 8 + 1.3·log2(N), capped at `KD_MAX_DEPTH`.
    pub max_depth: u32,
    /// A node with this many triangles or fewer becomes a leaf.
    pub leaf_size: u32,
}

impl Default for BuildSettings {
    fn default() -> Self {
        Self { max_depth: 0, leaf_size: 4 }
    }
}

#[derive(Clone, Debug, Default)]
pub struct KdTree {
    pub nodes: Vec<KdNode>,
    pub indices: Vec<u32>,
    pub bounds_min: Vec3,
    pub bounds_max: Vec3,
    pub depth: u32,
}

#[derive(Clone, Copy)]
struct Aabb {
    lo: Vec3,
    hi: Vec3,
}

fn triangle_box(t: &Triangle) -> Aabb {
    let (a, b, c) = (xyz(t.v0), xyz(t.v1), xyz(t.v2));
    Aabb { lo: a.min(b).min(c), hi: a.max(b).max(c) }
}

/// The automatic depth limit (pbrt-v3's 8 + 1.3·log2 N), never beyond the traversal stack.
pub fn default_max_depth(n: usize) -> u32 {
    let d = (8.0 + 1.3 * (n.max(1) as f64).log2()).round() as u32;
    d.min(KD_MAX_DEPTH)
}

/// Which children a box goes to for a split at `s` on `a`: (below, above).
fn sides(b: &Aabb, a: u32, s: f32) -> (bool, bool) {
    let (lo, hi) = (axis(b.lo, a), axis(b.hi, a));
    let planar = (lo == s) & (hi == s);
    (lo < s || planar, hi > s || planar)
}

pub fn build(triangles: &[Triangle], bounds_min: Vec3, bounds_max: Vec3, settings: BuildSettings) -> KdTree {
    let boxes: Vec<Aabb> = triangles.iter().map(triangle_box).collect();
    let max_depth = if settings.max_depth == 0 { default_max_depth(triangles.len()) } else { settings.max_depth.min(KD_MAX_DEPTH) };
    let mut tree = KdTree { bounds_min, bounds_max, ..Default::default() };
    let ids: Vec<u32> = (0..triangles.len() as u32).collect();
    let mut builder = Builder { boxes: &boxes, max_depth, leaf_size: settings.leaf_size.max(1), tree: &mut tree };
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
            if below.len() + above.len() > ids.len() + ids.len() / 2 || below.len() == ids.len() && above.len() == ids.len() {
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

/// Checks the tree's invariants; returns the first violation found.
///
/// Structure: every child index in range, the below child adjacent, leaf runs inside the index
/// list, triangle ids valid, splits finite and strictly inside the node's box, depth within
/// `KD_MAX_DEPTH`. Placement: every triangle appears in each leaf its bounding box overlaps.
pub fn validate(tree: &KdTree, triangles: &[Triangle]) -> Result<(), String> {
    if tree.nodes.is_empty() {
        return Err("no nodes".into());
    }
    let boxes: Vec<Aabb> = triangles.iter().map(triangle_box).collect();
    // (node, box, depth, triangles whose boxes reach this node)
    let mut stack = vec![(0usize, Aabb { lo: tree.bounds_min, hi: tree.bounds_max }, 0u32, (0..triangles.len() as u32).collect::<Vec<_>>())];
    let mut visited = 0usize;
    while let Some((i, b, depth, reaching)) = stack.pop() {
        visited += 1;
        if visited > tree.nodes.len() {
            return Err("a node is reachable twice (cycle or shared child)".into());
        }
        if depth > KD_MAX_DEPTH {
            return Err(format!("node {i} at depth {depth} > {KD_MAX_DEPTH}"));
        }
        let n = *tree.nodes.get(i).ok_or_else(|| format!("node index {i} out of range"))?;
        if n.is_leaf() {
            let (s, c) = (n.first_index() as usize, n.count() as usize);
            let run = tree.indices.get(s..s + c).ok_or_else(|| format!("leaf {i}: indices {s}..{} out of range", s + c))?;
            if let Some(&bad) = run.iter().find(|&&t| t as usize >= triangles.len()) {
                return Err(format!("leaf {i}: triangle id {bad} out of range"));
            }
            let mut listed = run.to_vec();
            listed.sort_unstable();
            for t in reaching {
                if listed.binary_search(&t).is_err() {
                    return Err(format!("leaf {i}: triangle {t} overlaps its box but is not listed"));
                }
            }
            continue;
        }
        let (a, s) = (n.axis(), n.split());
        if !s.is_finite() || s <= axis(b.lo, a) || s >= axis(b.hi, a) {
            return Err(format!("node {i}: split {s} on axis {a} not inside ({}, {})", axis(b.lo, a), axis(b.hi, a)));
        }
        let above = n.above_child() as usize;
        if above <= i + 1 || above >= tree.nodes.len() {
            return Err(format!("node {i}: above child {above} out of range"));
        }
        let (mut lo_box, mut hi_box) = (b, b);
        set_axis(&mut lo_box.hi, a, s);
        set_axis(&mut hi_box.lo, a, s);
        let below_ids = reaching.iter().filter(|&&t| sides(&boxes[t as usize], a, s).0).copied().collect();
        let above_ids = reaching.iter().filter(|&&t| sides(&boxes[t as usize], a, s).1).copied().collect();
        stack.push((i + 1, lo_box, depth + 1, below_ids));
        stack.push((above, hi_box, depth + 1, above_ids));
    }
    if visited != tree.nodes.len() {
        return Err(format!("{} of {} nodes reachable", visited, tree.nodes.len()));
    }
    Ok(())
}
