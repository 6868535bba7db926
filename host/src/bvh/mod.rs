//! The CPU's eight-wide BVH (`shared::wide_bvh`): a binary tree built by the binned surface area
//! heuristic (`binned`) with spatial splits (`spatial`), collapsed into nodes of up to eight children by opening, again and
//! again, the child of largest surface area (Wald, Benthin & Boulos, "Getting Rid of Packets",
//! RT 2008), its leaves laid out as blocks of the eight-lane triangle test.
//!
//! The GPU keeps the k-d tree: a GPU thread would test a node's eight boxes one after another.
mod binned;
mod reference;
mod spatial;
pub mod split;

use binned::{Kind, Node2};
use rayon::prelude::*;
use shared::glam::Vec3;
use shared::layout::{TriBlock, Triangle, BLOCK_WIDTH};
use shared::layout::{
    WideNode, WIDE_LEAF_BIT, WIDE_MAX_BLOCKS as MAX_BLOCKS, WIDE_MAX_DEPTH as MAX_DEPTH, WIDE_WIDTH as WIDTH,
};
use shared::scene::WideView;
use shared::vecmath::xyz;

/// The tree, its leaf blocks and the triangle id of every block lane.
#[derive(Default)]
pub struct WideBvh {
    pub nodes: Vec<WideNode>,
    pub blocks: Vec<TriBlock>,
    pub indices: Vec<u32>,
    /// Triangle references in the leaves: the triangles, and the copies spatial splits made.
    pub references: usize,
}

impl WideBvh {
    pub fn view(&self) -> WideView<'_> {
        WideView { nodes: &self.nodes, blocks: &self.blocks, indices: &self.indices }
    }

    /// Levels of nodes on the longest path from the root.
    pub fn depth(&self) -> usize {
        fn depth(nodes: &[WideNode], n: usize) -> usize {
            1 + nodes[n]
                .child
                .iter()
                .zip(0..WIDTH)
                .filter(|&(&c, l)| c & WIDE_LEAF_BIT == 0 && nodes[n].bounds[0][l] <= nodes[n].bounds[3][l])
                .map(|(&c, _)| depth(nodes, c as usize))
                .max()
                .unwrap_or(0)
        }
        if self.nodes.is_empty() {
            0
        } else {
            depth(&self.nodes, 0)
        }
    }
}

/// Builds the tree over all `triangles` (their ids are their positions).
pub fn build(triangles: &[Triangle]) -> WideBvh {
    if triangles.is_empty() {
        return WideBvh::default();
    }
    collapse(&binary(triangles, None, None), triangles)
}

/// The binary tree over `ids` of `triangles` (all of them for `None`), its leaves naming
/// triangles by their ids in `triangles`; `scene_area` as in `binned::build_in`.
fn binary(triangles: &[Triangle], ids: Option<&[u32]>, scene_area: Option<f32>) -> Node2 {
    let corners = |t: &Triangle| [xyz(t.v0), xyz(t.v1), xyz(t.v2)];
    let tris: Vec<[Vec3; 3]> = match ids {
        Some(ids) => ids.par_iter().map(|&i| corners(&triangles[i as usize])).collect(),
        None => triangles.par_iter().map(corners).collect(),
    };
    let budget = (binned::DUPLICATES * tris.len() as f32) as usize;
    let mut root = binned::build_in(&tris, 0, budget, scene_area);
    if let Some(ids) = ids {
        fn rename(n: &mut Node2, ids: &[u32]) {
            match &mut n.kind {
                Kind::Leaf { ids: leaf } => leaf.iter_mut().for_each(|i| *i = ids[*i as usize]),
                Kind::Inner(kids) => kids.iter_mut().for_each(|k| rename(k, ids)),
            }
        }
        rename(&mut root, ids);
    }
    root
}

/// The wide tree collapsed from the binary tree `root` over `triangles`.
fn collapse(root: &Node2, triangles: &[Triangle]) -> WideBvh {
    let mut out = WideBvh::default();
    let mut leaves = Vec::new();
    if let Kind::Leaf { .. } = root.kind {
        // A scene of one leaf: a root with one child.
        let mut n = WideNode::empty();
        set_lane(&mut n, 0, root, emit(root, &mut out.nodes, &mut leaves));
        out.nodes.push(n);
    } else {
        emit(root, &mut out.nodes, &mut leaves);
    }
    assert!(leaves.len() < MAX_BLOCKS as usize, "the wide BVH holds at most {MAX_BLOCKS} leaves");
    let width = BLOCK_WIDTH as usize;
    out.references = leaves.iter().map(|ids| ids.len()).sum();
    out.indices = leaves
        .iter()
        .flat_map(|ids| {
            // Ascending ids: the leaf test's tie rule relies on it.
            let mut run = ids.to_vec();
            run.sort_unstable();
            (0..width).map(move |l| run[l.min(run.len() - 1)])
        })
        .collect();
    out.blocks = out
        .indices
        .par_chunks(width)
        .map(|lanes| {
            let mut b = TriBlock::default();
            for (lane, &id) in lanes.iter().enumerate() {
                b.set_lane(lane, &triangles[id as usize]);
            }
            b
        })
        .collect();
    debug_assert!(out.depth() <= MAX_DEPTH);
    out
}

fn set_lane(n: &mut WideNode, lane: usize, child: &Node2, reference: u32) {
    let (lo, hi): (Vec3, Vec3) = (child.bounds.lo, child.bounds.hi);
    for a in 0..3 {
        n.bounds[a][lane] = lo[a];
        n.bounds[a + 3][lane] = hi[a];
    }
    n.child[lane] = reference;
}

/// Emits `n` (an inner node, or a leaf) and everything below it; returns its reference.
fn emit<'a>(n: &'a Node2, nodes: &mut Vec<WideNode>, leaves: &mut Vec<&'a [u32]>) -> u32 {
    let kids = match &n.kind {
        Kind::Leaf { ids } => {
            leaves.push(ids);
            return WideNode::leaf_ref(leaves.len() as u32 - 1, ids.len() as u32);
        }
        Kind::Inner(kids) => kids,
    };
    // Open the inner child of largest area until eight children or only leaves remain.
    let mut children: Vec<&Node2> = vec![&kids[0], &kids[1]];
    while children.len() < WIDTH {
        let open = children
            .iter()
            .enumerate()
            .filter(|(_, c)| matches!(c.kind, Kind::Inner(_)))
            .max_by(|a, b| a.1.bounds.half_area().total_cmp(&b.1.bounds.half_area()))
            .map(|(i, _)| i);
        let Some(i) = open else { break };
        let Kind::Inner(grand) = &children[i].kind else { unreachable!() };
        children[i] = &grand[0];
        children.insert(i + 1, &grand[1]);
    }
    let index = nodes.len();
    nodes.push(WideNode::empty());
    let mut node = WideNode::empty();
    for (lane, c) in children.iter().enumerate() {
        let r = emit(c, nodes, leaves);
        set_lane(&mut node, lane, c, r);
    }
    nodes[index] = node;
    index as u32
}
