//! The tree's layout while it is built. Wald & Havran 2006 ("On building fast kd-Trees for Ray
//! Tracing, and on doing that in O(N log N)") build depth first into one array; here the two
//! children of a large node are built in parallel, so each task lays its subtree out on its own
//! (`Subtree`, offsets relative to its own arrays), the splits above the tasks are kept as a
//! small tree of parts (`Part`), and the whole is written into arrays of the final size once at
//! the end. The result is the depth-first layout of the one-thread build whatever the number of
//! threads, and no node is copied more than once.
use shared::layout::KdNode;

/// A subtree laid out on its own: child and index offsets are relative to its own arrays.
#[derive(Default)]
pub(super) struct Subtree {
    pub(super) nodes: Vec<KdNode>,
    pub(super) indices: Vec<u32>,
    pub(super) depth: u32,
}

/// The top of the tree as the parallel tasks built it: subtrees each laid out on its own, joined
/// by the splits above them. Written out once at the end, into arrays of the final size, so no
/// node is copied more than once whatever the number of parallel levels.
pub(super) enum Part {
    Built(Subtree),
    Split { axis: u32, pos: f32, children: Box<(Part, Part)> },
}

impl Part {
    /// (nodes, indices) in all.
    pub(super) fn size(&self) -> (usize, usize) {
        match self {
            Part::Built(sub) => (sub.nodes.len(), sub.indices.len()),
            Part::Split { children, .. } => {
                let ((bn, bi), (an, ai)) = (children.0.size(), children.1.size());
                (1 + bn + an, bi + ai)
            }
        }
    }

    pub(super) fn write(self, out: &mut Subtree) {
        match self {
            Part::Built(sub) => out.append(sub),
            Part::Split { axis, pos, children } => {
                let (below, above) = *children;
                let me = out.nodes.len();
                out.nodes.push(KdNode::default());
                below.write(out);
                out.nodes[me] = KdNode::interior(axis, pos, out.nodes.len() as u32);
                above.write(out);
            }
        }
    }
}

impl Subtree {
    /// Appends `other`, its child and index offsets moved past what this subtree holds.
    fn append(&mut self, other: Subtree) {
        let (node_base, index_base) = (self.nodes.len() as u32, self.indices.len() as u32);
        self.nodes.extend(other.nodes.into_iter().map(|n| {
            if n.is_leaf() {
                KdNode::leaf(n.first_index() + index_base, n.count())
            } else {
                KdNode::interior(n.axis(), n.split(), n.above_child() + node_base)
            }
        }));
        self.indices.extend_from_slice(&other.indices);
        self.depth = self.depth.max(other.depth);
    }

    /// Appends a leaf of `triangles` (sorted, so the leaf's order does not depend on the
    /// partition's) at `depth`.
    #[inline]
    pub(super) fn leaf(&mut self, triangles: &mut [u32], depth: u32) {
        triangles.sort_unstable();
        self.nodes.push(KdNode::leaf(self.indices.len() as u32, triangles.len() as u32));
        self.indices.extend_from_slice(triangles);
        self.depth = self.depth.max(depth);
    }
}
