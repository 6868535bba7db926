//! Every invariant the traversal in `shared::kdtree` relies on, checked on a built tree.
//!
//! Structure (`check_structure`, also what a `.kdc` file's tree must pass before it is used):
//! child indices in range with the below child adjacent and the above child after it (so no
//! path can cycle), every node reachable exactly once, leaf runs inside the index list, triangle
//! ids in range, splits finite, depth within `KD_MAX_DEPTH`. Linear in the node count: a crafted
//! tree that shares subtrees cannot make the walk explode.
//!
//! Geometry (`validate`, far slower): split planes inside (or on the boundary of) the node's
//! voxel.
//!
//! Placement: each triangle is clipped exactly (in f64) to each node's voxel; a triangle whose
//! clipped part reaches strictly into a child's half must be referenced in that child, and one
//! lying in the split plane itself must be referenced on at least one side. At the leaves this
//! means every triangle is listed in every leaf its clipped part overlaps: the traversal visits
//! all leaves along a ray, so it cannot miss a hit.
use super::clip::{clip_polygon, to_f64, Aabb, Tri64};
use super::KdTree;
use shared::layout::{KdNode, Triangle, KD_MAX_DEPTH};

/// Relative distance from a split plane within which a clipped part counts as lying in it:
/// f64 clipping rounds the cut vertices by about 1e-16, far below the f32 rounding of the
/// builder's boxes and the traversal's slack.
const PLANE_TOLERANCE: f64 = 1e-12;

/// The tree's structure (module docs); returns its depth.
pub fn check_structure(nodes: &[KdNode], indices: &[u32], triangles: usize) -> Result<u32, String> {
    if let Some(&bad) = indices.iter().find(|&&t| t as usize >= triangles) {
        return Err(format!("triangle index {bad} out of range ({triangles} triangles)"));
    }
    let n = nodes.len();
    if n == 0 {
        return Err("no nodes".into());
    }
    let mut stack: Vec<(u32, u32)> = Vec::with_capacity(2 * KD_MAX_DEPTH as usize + 2);
    stack.push((0, 0));
    let (mut visited, mut max_depth) = (0usize, 0u32);
    // One flag a node: a node reached twice (a shared subtree) is an error at once, so counting
    // cannot be fooled by one node reached twice and another never.
    let mut reached = vec![false; n];
    while let Some((i, depth)) = stack.pop() {
        let i = i as usize;
        if i >= n {
            return Err(format!("node index {i} out of range ({n} nodes)"));
        }
        if std::mem::replace(&mut reached[i], true) {
            return Err(format!("node {i} is reached twice: subtrees are shared"));
        }
        visited += 1;
        if depth > KD_MAX_DEPTH {
            return Err(format!("node {i} at depth {depth}, beyond {KD_MAX_DEPTH}"));
        }
        max_depth = max_depth.max(depth);
        let node = nodes[i];
        if node.is_leaf() {
            let (first, count) = (node.first_index() as u64, node.count() as u64);
            if first + count > indices.len() as u64 {
                return Err(format!(
                    "leaf {i}: indices {first}..{} beyond the {} in the list",
                    first + count,
                    indices.len()
                ));
            }
            continue;
        }
        if !node.split().is_finite() || node.axis() > 2 {
            return Err(format!("node {i}: split {} on axis {} not finite", node.split(), node.axis()));
        }
        let above = node.above_child() as usize;
        if i + 1 >= n || above <= i + 1 || above >= n {
            return Err(format!("node {i}: children {} and {above} out of range ({n} nodes)", i + 1));
        }
        stack.push((above as u32, depth + 1));
        stack.push((i as u32 + 1, depth + 1));
    }
    if visited != n {
        return Err(format!("{} of {n} nodes unreachable", n - visited));
    }
    Ok(max_depth)
}

pub fn validate(tree: &KdTree, triangles: &[Triangle]) -> Result<(), String> {
    check_structure(&tree.nodes, &tree.indices, triangles.len())?;
    let tris: Vec<Tri64> = triangles.iter().map(to_f64).collect();
    let root = Aabb { lo: tree.bounds_min.to_array(), hi: tree.bounds_max.to_array() };
    if (0..3).any(|k| root.lo[k].is_nan() || root.hi[k].is_nan() || root.lo[k] > root.hi[k]) {
        return Err(format!("root box {root:?} is empty or not finite"));
    }
    let reaching_root: Vec<u32> =
        (0..tris.len() as u32).filter(|&t| clip_polygon(&tris[t as usize], &root).is_none_or(|p| p.len > 0)).collect();
    let mut stack = vec![(0usize, root, reaching_root)];
    while let Some((i, voxel, reaching)) = stack.pop() {
        let n = tree.nodes[i];
        if n.is_leaf() {
            let listed = leaf_run(tree, i, triangles.len())?;
            for t in reaching {
                if listed.binary_search(&t).is_err() {
                    return Err(format!("leaf {i} (voxel {voxel:?}): triangle {t} overlaps it but is not listed"));
                }
            }
            continue;
        }
        let (k, s) = (n.axis() as usize, n.split());
        if k > 2 || !s.is_finite() || s < voxel.lo[k] || s > voxel.hi[k] {
            return Err(format!("node {i}: split {s} on axis {k} outside [{}, {}]", voxel.lo[k], voxel.hi[k]));
        }
        let above = n.above_child() as usize;
        let (below_voxel, above_voxel) = voxel.split(k, s);
        let tolerance = PLANE_TOLERANCE * (s as f64).abs().max(voxel.extent(k));
        let (mut below_ids, mut above_ids) = (Vec::new(), Vec::new());
        for t in reaching {
            let Some(poly) = clip_polygon(&tris[t as usize], &voxel) else {
                // Clipping overflowed (degenerate input): require both sides, as the builder's
                // fallback to the unclipped box does.
                below_ids.push(t);
                above_ids.push(t);
                continue;
            };
            if poly.len == 0 {
                continue;
            }
            let (lo, hi) = poly.range(k);
            let (b, a) = (lo < s as f64 - tolerance, hi > s as f64 + tolerance);
            if b {
                below_ids.push(t);
            }
            if a {
                above_ids.push(t);
            }
            if !b && !a {
                // In the plane: the builder puts it on one side of its choosing.
                if listed_under(tree, i + 1, &below_voxel, &tris[t as usize], t) {
                    below_ids.push(t);
                } else if listed_under(tree, above, &above_voxel, &tris[t as usize], t) {
                    above_ids.push(t);
                } else {
                    return Err(format!(
                        "node {i}: triangle {t} lies in split plane {s} (axis {k}) but neither child lists it"
                    ));
                }
            }
        }
        stack.push((i + 1, below_voxel, below_ids));
        stack.push((above, above_voxel, above_ids));
    }
    Ok(())
}

/// The sorted triangle ids of leaf `i`, checked against the index list and triangle count.
fn leaf_run(tree: &KdTree, i: usize, triangles: usize) -> Result<Vec<u32>, String> {
    let n = tree.nodes[i];
    let (s, c) = (n.first_index() as usize, n.count() as usize);
    let run = tree.indices.get(s..s + c).ok_or_else(|| format!("leaf {i}: indices {s}..{} out of range", s + c))?;
    if let Some(&bad) = run.iter().find(|&&t| t as usize >= triangles) {
        return Err(format!("leaf {i}: triangle id {bad} out of range"));
    }
    let mut listed = run.to_vec();
    listed.sort_unstable();
    Ok(listed)
}

/// Whether some leaf under `node` whose voxel the triangle touches lists it.
fn listed_under(tree: &KdTree, node: usize, voxel: &Aabb, tri: &Tri64, id: u32) -> bool {
    let mut stack = vec![(node, *voxel)];
    while let Some((i, v)) = stack.pop() {
        let Some(&n) = tree.nodes.get(i) else { return false };
        if clip_polygon(tri, &v).is_some_and(|p| p.len == 0) {
            continue;
        }
        if n.is_leaf() {
            let (s, c) = (n.first_index() as usize, n.count() as usize);
            if tree.indices.get(s..s + c).is_some_and(|run| run.contains(&id)) {
                return true;
            }
            continue;
        }
        let (b, a) = v.split(n.axis() as usize, n.split());
        stack.push((i + 1, b));
        stack.push((n.above_child() as usize, a));
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Found by the `kdc_reader` fuzz target: node 2 reached from two parents and node 4 from
    /// none make as many visits as there are nodes, so a count alone passed the tree, and the
    /// unreachable leaf's index range (far beyond the list) was later sliced.
    #[test]
    fn a_shared_node_and_an_unreachable_one_are_refused() {
        let nodes = [
            KdNode::interior(0, 0.5, 2),
            KdNode::interior(1, 0.5, 3),
            KdNode::leaf(0, 1),
            KdNode::leaf(0, 1),
            KdNode::leaf(0x8000_0076, 0),
        ];
        let e = check_structure(&nodes, &[0], 1).unwrap_err();
        assert!(e.contains("reached twice"), "{e}");
        // The same tree without the shared node is sound.
        let sound = [KdNode::interior(0, 0.5, 2), KdNode::leaf(0, 1), KdNode::leaf(0, 1)];
        assert_eq!(check_structure(&sound, &[0], 1), Ok(1));
    }
}
