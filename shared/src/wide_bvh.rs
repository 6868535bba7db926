//! The CPU's eight-wide BVH and its traversal: one node holds the boxes of up to eight children,
//! tested in the eight lanes of an AVX register, and every leaf is one `TriBlock` of up to eight
//! triangles, tested in the same lanes (Wald, Benthin & Boulos, "Getting Rid of Packets:
//! Efficient SIMD Single-Ray Traversal using Multi-branching BVHs", RT 2008; Embree's BVH8).
//!
//! The k-d tree's single-ray traversal is a chain of dependent steps, each with a branch the
//! predictor cannot learn; here one step tests eight boxes at once and the far children wait on
//! a stack in order of entry distance. The host builds the tree (`host::bvh`; its layout is
//! `layout::WideNode`); the GPU keeps the k-d tree.
//!
//! The result is the k-d tree's: the closest hit that counts (alpha masks as in `kdtree`) in
//! (0, t_max), by the same lane-wise watertight test, so it equals brute force bit for bit; of
//! triangles hit at exactly the same distance (coincident faces) the lowest id, as brute force
//! picks, whatever order the leaves come in. Box tests are conservative: the slab distances
//! carry about γ(3) of relative error and a hit's own distance a few ulps, so a box's exit is
//! widened and its entry compared to the closest hit lowered, both by `T_SLACK` as in the k-d
//! traversal. A ray parallel to an axis's planes (a zero direction component) forms no distance
//! on that axis, which would be `0·∞ = NaN` for a ray in a box's face: its origin is tested
//! against the slab instead.
use crate::glam::Vec3;
use crate::kdtree::{safe_reciprocal, test_block_run, usable_direction, Hit};
use crate::layout::{TriBlock, WideNode, WIDE_LEAF_BIT as LEAF_BIT, WIDE_MAX_DEPTH as MAX_DEPTH, WIDE_WIDTH as WIDTH};
use crate::numerics::T_SLACK;
use crate::scene::{SceneView, WideView};
use crate::triangle::RayShear;
use crate::vecmath::axis;
use core::mem::MaybeUninit;
use core::simd::cmp::SimdPartialOrd;
use core::simd::Select;
use core::simd::{Mask, Simd};

/// The traversal's stack: the seven siblings each level may leave behind, and the root.
const STACK_SIZE: usize = (WIDTH - 1) * MAX_DEPTH + 1;

type Lanes = Simd<f32, WIDTH>;

/// `a > b ? a : b` lane by lane: one `vmaxps` (no NaN can reach it, see the module docs).
#[inline(always)]
fn max(a: Lanes, b: Lanes) -> Lanes {
    a.simd_gt(b).select(a, b)
}

/// `a < b ? a : b` lane by lane: one `vminps`.
#[inline(always)]
fn min(a: Lanes, b: Lanes) -> Lanes {
    a.simd_lt(b).select(a, b)
}

/// The most 64-byte cache lines one `T` in an array can touch: its size plus the most it can
/// start past a line's start (a line less its alignment), in lines (a node: four, a leaf block:
/// five).
#[cfg(target_arch = "x86_64")]
const fn lines_spanned<T>() -> usize {
    (core::mem::size_of::<T>() + 64usize.saturating_sub(core::mem::align_of::<T>())).div_ceil(64)
}

/// Asks the cache for a child's node or leaf block (x86-64 only; nothing elsewhere).
#[inline(always)]
fn prefetch(tree: &WideView, child: u32) {
    #[cfg(target_arch = "x86_64")]
    {
        use core::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let (p, lines) = if child & LEAF_BIT == 0 {
            (tree.nodes.as_ptr().wrapping_add(child as usize) as *const i8, lines_spanned::<WideNode>())
        } else {
            let k = WideNode::leaf_of(child).0 as usize;
            (tree.blocks.as_ptr().wrapping_add(k) as *const i8, lines_spanned::<TriBlock>())
        };
        for l in 0..lines {
            // SAFETY: a prefetch reads nothing and never faults, whatever the address.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * l)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (tree, child);
}

#[derive(Clone, Copy)]
struct Entry {
    child: u32,
    t: f32,
}

/// The closest (or, with `any_hit`, any) hit in (0, t_max) that counts. The hit's `nodes` counts
/// wide nodes visited, `tests` the triangles of the leaves tested.
#[inline(always)]
pub fn traverse(scene: &SceneView, origin: Vec3, dir: Vec3, t_max: f32, any_hit: bool) -> Hit {
    if scene.alpha_masks {
        traverse_from::<true>(scene, scene.wide, 0, origin, dir, Hit::miss(t_max), any_hit)
    } else {
        traverse_from::<false>(scene, scene.wide, 0, origin, dir, Hit::miss(t_max), any_hit)
    }
}

/// The traversal of the subtree under `root` (a node or leaf reference; 0 is the whole tree)
/// of `tree` (the scene's, or another over some of its triangles) for a ray whose closest hit
/// so far is `best`: a hit in the subtree replaces it where `traverse` would. `nodes` and
/// `tests` count this subtree's work alone.
#[inline(always)]
pub(crate) fn traverse_from<const MASKS: bool>(
    scene: &SceneView,
    tree: WideView,
    root: u32,
    origin: Vec3,
    dir: Vec3,
    mut best: Hit,
    any_hit: bool,
) -> Hit {
    if tree.nodes.is_empty() {
        return best;
    }
    let Some(dir) = usable_direction(origin, dir) else { return best };
    let shear = RayShear::new(origin, dir);
    // Per axis: the origin, the reciprocal, which of a node's bound rows is the near one (the
    // lower for a positive direction) and whether the ray is parallel to the axis's planes.
    let mut o = [Lanes::splat(0.0); 3];
    let mut r = [Lanes::splat(0.0); 3];
    let mut near = [0usize; 3];
    let mut flat = [false; 3];
    let inv = safe_reciprocal(dir);
    for a in 0..3 {
        let d = axis(dir, a as u32);
        o[a] = Lanes::splat(axis(origin, a as u32));
        flat[a] = d == 0.0;
        r[a] = Lanes::splat(axis(inv, a as u32));
        near[a] = if d < 0.0 { a + 3 } else { a };
    }
    let any_flat = flat[0] | flat[1] | flat[2];
    let far = [(near[0] + 3) % 6, (near[1] + 3) % 6, (near[2] + 3) % 6];
    let zero = Lanes::splat(0.0);
    let widen = Lanes::splat(1.0 + T_SLACK);
    let shrink = 1.0 - T_SLACK;
    // Uninitialised: zeroing the whole stack for every ray would cost more than most rays'
    // traversal; only slots below `sp` are read, and each was written first.
    let mut stack = [MaybeUninit::<Entry>::uninit(); STACK_SIZE];
    let mut sp = 0usize;
    let mut child = root;
    let mut nodes = 0u32;
    let mut tests = 0u32;
    loop {
        if child & LEAF_BIT == 0 {
            nodes += 1;
            let n = &tree.nodes[child as usize];
            let b = &n.bounds;
            // (b − o)·r, not a fused b·r − o·r: at a box face through the origin the
            // difference is exactly zero, so a ray leaving a surface still enters its box.
            let tn = |a: usize| (Lanes::from_array(b[near[a]]) - o[a]) * r[a];
            let tf = |a: usize| (Lanes::from_array(b[far[a]]) - o[a]) * r[a];
            let (t_in, t_out, inside) = if any_flat {
                // Rare: a parallel axis bounds nothing along the ray, the origin must lie in
                // its slab (closed: a ray in a box's face enters the box).
                let (mut t_in, mut t_out, mut inside) = (zero, Lanes::splat(f32::INFINITY), Mask::splat(true));
                for a in 0..3 {
                    if flat[a] {
                        let (lo, hi) = (Lanes::from_array(b[a]), Lanes::from_array(b[a + 3]));
                        inside &= lo.simd_le(o[a]) & o[a].simd_le(hi);
                    } else {
                        t_in = max(t_in, tn(a));
                        t_out = min(t_out, tf(a));
                    }
                }
                (t_in, t_out * widen, inside)
            } else {
                let t_in = max(max(tn(0), tn(1)), max(tn(2), zero));
                (t_in, min(min(tf(0), tf(1)), tf(2)) * widen, Mask::splat(true))
            };
            let reach = Lanes::splat(best.t);
            let hit = inside & t_in.simd_le(t_out) & (t_in * Lanes::splat(shrink)).simd_le(reach);
            let mut mask = hit.to_bitmask() as u32;
            if mask != 0 {
                let ts = t_in.to_array();
                if mask & (mask - 1) == 0 {
                    child = n.child[mask.trailing_zeros() as usize];
                    continue;
                }
                // Several: ask the cache for each now, so that a far child popped later need not
                // wait for its loads (the traversal is a chain of dependent loads).
                let mut all = mask;
                while all != 0 {
                    prefetch(&tree, n.child[all.trailing_zeros() as usize]);
                    all &= all - 1;
                }
                // Push all but the nearest, farthest first, and go on to the nearest.
                // The builder bounds the depth by `MAX_DEPTH`, so the stack cannot overflow on a
                // tree it made; the guard only keeps a corrupt tree from writing out of bounds.
                if sp + WIDTH <= STACK_SIZE {
                    let (l0, rest) = (mask.trailing_zeros() as usize, mask & (mask - 1));
                    let l1 = rest.trailing_zeros() as usize;
                    let (a, b) = (Entry { child: n.child[l0], t: ts[l0] }, Entry { child: n.child[l1], t: ts[l1] });
                    let (close, far) = if b.t < a.t { (b, a) } else { (a, b) };
                    if rest & (rest - 1) == 0 {
                        // Two, the commonest case: one comparison.
                        stack[sp] = MaybeUninit::new(far);
                        sp += 1;
                        child = close.child;
                        continue;
                    }
                    // Three or more: insertion into the run pushed for this node, kept farthest
                    // first, then the nearest comes off the top.
                    let base = sp;
                    stack[sp] = MaybeUninit::new(far);
                    stack[sp + 1] = MaybeUninit::new(close);
                    sp += 2;
                    mask = rest & (rest - 1);
                    while mask != 0 {
                        let l = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        let e = Entry { child: n.child[l], t: ts[l] };
                        let mut i = sp;
                        // SAFETY: base <= i - 1 < sp: a slot written before.
                        while (i > base) && (unsafe { stack[i - 1].assume_init() }.t < e.t) {
                            stack[i] = stack[i - 1];
                            i -= 1;
                        }
                        stack[i] = MaybeUninit::new(e);
                        sp += 1;
                    }
                    sp -= 1;
                    // SAFETY: slot sp was written above.
                    child = unsafe { stack[sp].assume_init() }.child;
                    continue;
                }
            }
        } else {
            let (k, count) = WideNode::leaf_of(child);
            tests += count;
            if test_block_run::<MASKS, true>(scene, tree.blocks, tree.indices, k, k + 1, &shear, &mut best, any_hit) {
                break;
            }
        }
        // Pop the nearest child that may still hold a closer hit.
        let mut found = false;
        while (sp > 0) & !found {
            sp -= 1;
            // SAFETY: every slot below the stack pointer was written by a push.
            let e = unsafe { stack[sp].assume_init() };
            if e.t * shrink <= best.t {
                child = e.child;
                found = true;
            }
        }
        if !found {
            break;
        }
    }
    best.nodes = nodes;
    best.tests = tests;
    best
}
