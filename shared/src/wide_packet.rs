//! Packets of up to sixteen rays through the CPU's wide BVH: each node is loaded once for every
//! ray of the packet that reaches it, its eight child boxes tested one after another against all
//! of those rays in the sixteen lanes of a register (Wald, Slusallek, Benthin & Wagner,
//! "Interactive Rendering with Coherent Ray Tracing", EG 2001; Embree's BVH8 packet
//! intersectors), and each leaf block tested ray by ray with `wide_bvh`'s lane-wise watertight
//! test.
//!
//! A packet visits the union of its rays' nodes, in the order of the nearest entry among its
//! rays; a child is entered with the mask of the rays whose box test it passed, and a ray whose
//! hit has come closer than its entry distance drops out when the child is taken off the stack.
//! A node that only `SWITCH` or fewer of the packet's rays reach is traversed by each of them
//! alone (`wide_bvh::traverse_from`, its hit so far carried in), as Embree's hybrid
//! traversal does: incoherent rays part after the first few nodes.
//! The box test is `wide_bvh`'s, value for value (the near and far planes chosen by the sign of
//! each ray's direction, the same slack), and the leaf test is the same function, so every ray
//! gets exactly the hit `wide_bvh::traverse` gives it: the closest in (0, t_max), the lowest
//! triangle id among ties. Rays parallel to an axis's planes are traced alone by
//! `wide_bvh::traverse`. `nodes` counts the wide nodes a ray was active in, `tests` the
//! triangles tested for it.
use crate::glam::Vec3;
use crate::kdtree::{safe_reciprocal, test_block_run, usable_direction, Hit};
use crate::layout::{WideNode, WIDE_LEAF_BIT as LEAF_BIT, WIDE_MAX_DEPTH as MAX_DEPTH, WIDE_WIDTH as WIDTH};
use crate::numerics::T_SLACK;
use crate::scene::SceneView;
use crate::triangle::RayShear;
use crate::wide_bvh;
use core::mem::MaybeUninit;
use core::simd::cmp::SimdPartialOrd;
use core::simd::num::SimdFloat;
use core::simd::{Mask, Select, Simd};

/// Rays in a packet: the lanes of one AVX-512 register.
pub const PACKET: usize = 16;

/// A node reached by this many of the packet's rays or fewer is traversed by each of them
/// alone (Benthin et al., "Combining Single and Packet-Ray Tracing for Arbitrary Ray
/// Distributions on the Intel MIC Architecture", TVCG 2012; Embree's hybrid traversal): a
/// sixteen-lane box test does little more for a few rays than an eight-lane one for each.
pub const SWITCH: u32 = 5;

type Rays = Simd<f32, PACKET>;
type RayMask = Mask<i32, PACKET>;

/// The stack: the seven siblings each level may leave behind, and the root.
const STACK_SIZE: usize = (WIDTH - 1) * MAX_DEPTH + 1;

#[derive(Clone, Copy)]
struct Entry {
    child: u32,
    /// The rays that entered the child's box.
    rays: u32,
    /// Each ray's entry distance into it.
    t: Rays,
    /// The nearest of those (the stack's order).
    near: f32,
}

/// `a > b ? a : b` lane by lane, as `wide_bvh`'s.
#[inline(always)]
fn max(a: Rays, b: Rays) -> Rays {
    a.simd_gt(b).select(a, b)
}

/// `a < b ? a : b` lane by lane, as `wide_bvh`'s.
#[inline(always)]
fn min(a: Rays, b: Rays) -> Rays {
    a.simd_lt(b).select(a, b)
}

#[inline(always)]
fn lanes(mask: u32) -> RayMask {
    RayMask::from_bitmask(mask as u64)
}

/// The closest (or, with `any_hit`, any) hit in (0, t_max\[i\]) of rays `0..count` (at most
/// `PACKET`), each what `wide_bvh::traverse` returns for it.
#[inline(always)]
pub fn traverse(
    scene: &SceneView,
    origin: &[Vec3; PACKET],
    dir: &[Vec3; PACKET],
    t_max: &[f32; PACKET],
    count: usize,
    any_hit: bool,
) -> [Hit; PACKET] {
    if scene.alpha_masks {
        traverse_with::<true>(scene, origin, dir, t_max, count, any_hit)
    } else {
        traverse_with::<false>(scene, origin, dir, t_max, count, any_hit)
    }
}

#[inline(always)]
fn traverse_with<const MASKS: bool>(
    scene: &SceneView,
    origin: &[Vec3; PACKET],
    dir: &[Vec3; PACKET],
    t_max: &[f32; PACKET],
    count: usize,
    any_hit: bool,
) -> [Hit; PACKET] {
    let mut best = [Hit::miss(0.0); PACKET];
    let count = count.min(PACKET);
    for i in 0..count {
        best[i] = Hit::miss(t_max[i]);
    }
    let tree = scene.wide;
    if tree.nodes.is_empty() {
        return best;
    }
    // Per ray: the watertight test's constants; per axis and lane: the origin, the reciprocal
    // and whether the direction is negative (the near plane is then the upper bound).
    let mut shear = [RayShear::new(Vec3::ZERO, Vec3::Z); PACKET];
    let mut o = [[0.0f32; PACKET]; 3];
    let mut r = [[0.0f32; PACKET]; 3];
    let mut neg = [0u32; 3];
    let mut active = 0u32;
    for i in 0..count {
        let Some(d) = usable_direction(origin[i], dir[i]) else { continue };
        if (d.x == 0.0) | (d.y == 0.0) | (d.z == 0.0) {
            // Parallel to an axis's planes: `wide_bvh` tests the origin against that slab.
            best[i] = wide_bvh::traverse(scene, origin[i], dir[i], t_max[i], any_hit);
            continue;
        }
        shear[i] = RayShear::new(origin[i], d);
        let inv = safe_reciprocal(d);
        for a in 0..3 {
            o[a][i] = origin[i][a];
            r[a][i] = inv[a];
            neg[a] |= ((d[a] < 0.0) as u32) << i;
        }
        active |= 1 << i;
    }
    if active == 0 {
        return best;
    }
    let o = o.map(Rays::from_array);
    let r = r.map(Rays::from_array);
    let neg = neg.map(lanes);
    let zero = Rays::splat(0.0);
    let widen = Rays::splat(1.0 + T_SLACK);
    let shrink = Rays::splat(1.0 - T_SLACK);
    let mut reach = Rays::from_array(core::array::from_fn(|i| best[i].t));
    let mut nodes = Simd::<u32, PACKET>::splat(0);
    let mut tests = [0u32; PACKET];
    let one = Simd::<u32, PACKET>::splat(1);
    // Rays whose any-hit query is answered.
    let mut done = 0u32;
    // Uninitialised, as in `wide_bvh`: only slots below `sp` are read, each written first.
    let mut stack = [MaybeUninit::<Entry>::uninit(); STACK_SIZE];
    let mut sp = 0usize;
    let mut child = 0u32;
    let mut rays = active;
    loop {
        if (child & LEAF_BIT == 0) & (rays.count_ones() <= SWITCH) {
            // Few rays left in this subtree: each goes on alone from here, its hit so far kept.
            let mut left = rays;
            while left != 0 {
                let i = left.trailing_zeros() as usize;
                left &= left - 1;
                let h = wide_bvh::traverse_from::<MASKS>(scene, scene.wide, child, origin[i], dir[i], best[i], any_hit);
                tests[i] += h.tests;
                nodes[i] += h.nodes;
                if any_hit & h.is_hit() {
                    done |= 1 << i;
                }
                best[i] = Hit { nodes: 0, tests: 0, ..h };
                reach[i] = best[i].t;
            }
            if done == active {
                break;
            }
        } else if child & LEAF_BIT == 0 {
            nodes += lanes(rays).select(one, Simd::splat(0));
            let n = &tree.nodes[child as usize];
            let b = &n.bounds;
            let m = lanes(rays);
            // Each child's box against every ray of the packet; the children reached, with
            // their rays and the nearest of those rays' entry distances.
            let mut masks = [0u32; WIDTH];
            let mut t_in = [zero; WIDTH];
            let mut nearest = [f32::INFINITY; WIDTH];
            let mut reached = 0u32;
            for c in 0..WIDTH {
                if b[0][c] > b[3][c] {
                    // An empty slot.
                    continue;
                }
                // (b − o)·r with the near and far planes of each ray's direction, as in
                // `wide_bvh`: the same values, so the same boxes are entered.
                let slab = |a: usize| {
                    let (lo, hi) = (Rays::splat(b[a][c]), Rays::splat(b[a + 3][c]));
                    let (near, far) = (neg[a].select(hi, lo), neg[a].select(lo, hi));
                    ((near - o[a]) * r[a], (far - o[a]) * r[a])
                };
                let ((n0, f0), (n1, f1), (n2, f2)) = (slab(0), slab(1), slab(2));
                let enter = max(max(n0, n1), max(n2, zero));
                let exit = min(min(f0, f1), f2) * widen;
                let hit = m & enter.simd_le(exit) & (enter * shrink).simd_le(reach);
                let bits = hit.to_bitmask() as u32;
                if bits != 0 {
                    masks[c] = bits;
                    t_in[c] = enter;
                    nearest[c] = hit.select(enter, Rays::splat(f32::INFINITY)).reduce_min();
                    reached |= 1 << c;
                }
            }
            if reached != 0 {
                if reached & (reached - 1) == 0 {
                    let c = reached.trailing_zeros() as usize;
                    child = n.child[c];
                    rays = masks[c];
                    continue;
                }
                // Several: push them farthest first (insertion by the nearest ray's entry),
                // then go on to the nearest. The builder bounds the depth, so the stack cannot
                // overflow on a tree it made; the guard keeps a corrupt one in bounds.
                if sp + WIDTH <= STACK_SIZE {
                    let base = sp;
                    let mut left = reached;
                    while left != 0 {
                        let c = left.trailing_zeros() as usize;
                        left &= left - 1;
                        let e = Entry { child: n.child[c], rays: masks[c], t: t_in[c], near: nearest[c] };
                        let mut i = sp;
                        // SAFETY: base <= i - 1 < sp: a slot written before.
                        while (i > base) && (unsafe { stack[i - 1].assume_init() }.near < e.near) {
                            stack[i] = stack[i - 1];
                            i -= 1;
                        }
                        stack[i] = MaybeUninit::new(e);
                        sp += 1;
                    }
                    sp -= 1;
                    // SAFETY: slot sp was written above.
                    let e = unsafe { stack[sp].assume_init() };
                    child = e.child;
                    rays = e.rays;
                    continue;
                }
            }
        } else {
            let (k, count) = WideNode::leaf_of(child);
            let mut left = rays;
            while left != 0 {
                let i = left.trailing_zeros() as usize;
                left &= left - 1;
                tests[i] += count;
                if test_block_run::<MASKS, true>(
                    scene,
                    tree.blocks,
                    tree.indices,
                    k,
                    k + 1,
                    &shear[i],
                    &mut best[i],
                    any_hit,
                ) {
                    done |= 1 << i;
                }
                reach[i] = best[i].t;
            }
            if done == active {
                break;
            }
        }
        // Pop the nearest child that still has a ray whose hit may lie in it.
        let mut found = false;
        while (sp > 0) & !found {
            sp -= 1;
            // SAFETY: every slot below the stack pointer was written by a push.
            let e = unsafe { stack[sp].assume_init() };
            let still = (lanes(e.rays & !done) & (e.t * shrink).simd_le(reach)).to_bitmask() as u32;
            if still != 0 {
                child = e.child;
                rays = still;
                found = true;
            }
        }
        if !found {
            break;
        }
    }
    let nodes = nodes.to_array();
    for i in 0..count {
        if active & (1 << i) != 0 {
            best[i].nodes = nodes[i];
            best[i].tests = tests[i];
        }
    }
    best
}
