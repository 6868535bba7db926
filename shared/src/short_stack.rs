//! Short-stack k-d traversal with restart: Horn, Sugerman, Houston & Hanrahan, "Interactive k-D
//! Tree GPU Raytracing" (I3D 2007), after Foley & Sugerman's kd-restart (Graphics Hardware 2005).
//!
//! The traversal of `kdtree` with a stack of only `S` entries, kept as a ring: pushing onto a
//! full stack drops the oldest entry (the farthest along the ray, but for rays lying in split
//! planes). When the stack runs dry after entries were dropped, everything before the nearest
//! dropped entry has been visited, so the traversal restarts from the root with the ray clipped
//! to start there.
//! With a stack as deep as the tree it never restarts and does exactly what `kdtree::intersect`
//! does; with any `S ≥ 1` it returns the same hit (tested against brute force).
//!
//! Restarting needs progress along the ray. A ray lying exactly in a split plane visits both
//! halves over the same interval, so a dropped entry may start where the traversal already is;
//! when a restart would not move forward, that ray finishes with the full-stack traversal
//! (counted as a restart). Such rays are rare outside adversarial tests.
//!
//! A small stack is what makes a k-d traversal fit in a GPU thread's registers.
//!
//! One loop serves both stacks (`traverse`'s `short`): the full-stack traversal of
//! `kdtree::traverse` and the fall-back are this loop with the full stack chosen. A shader
//! inlines the traversal, leaf test and alpha lookups included, at every query of the
//! integrator; one loop for both stacks, where there were three (the short stack, its fall-back
//! and the full stack), keeps the kernel much smaller, and a driver's compile time grows
//! faster than the kernel does (README, "Shader size").
use crate::glam::Vec3;
use crate::kdtree::{descend, may_hold_closer, ray_start, test_leaf, Hit, Stack, StackEntry, STACK_SIZE};
use crate::record::{NoRecord, Recorder};
use crate::scene::SceneView;
use crate::triangle::RayShear;

/// The stack depth the renderer uses on both devices.
pub const SHORT_STACK: usize = 4;

/// The closest hit with t in (0, t_max), traversing with an `S`-entry stack (`S ≥ 1`).
#[inline]
pub fn intersect_short<const S: usize>(scene: &SceneView, origin: Vec3, dir: Vec3, t_max: f32) -> ShortHit {
    traverse::<S, _>(scene, origin, dir, t_max, false, true, &mut NoRecord)
}

/// Any hit with t in (0, t_max).
#[inline]
pub fn occluded_short<const S: usize>(scene: &SceneView, origin: Vec3, dir: Vec3, t_max: f32) -> ShortHit {
    traverse::<S, _>(scene, origin, dir, t_max, true, true, &mut NoRecord)
}

/// A hit and how many times the traversal restarted from the root.
#[derive(Clone, Copy, Debug)]
pub struct ShortHit {
    pub hit: Hit,
    pub restarts: u32,
}

/// The k-d traversal with the `S`-entry ring (`short`) or the full stack; `rec` hears of every
/// node visited (`Recorder::node`), the root again after each restart, and the full traversal's
/// nodes where the short stack falls back to it. On the CPU a scene without alpha masks runs the
/// leaf test compiled without them (`test_blocks`).
#[inline]
pub(crate) fn traverse<const S: usize, R: Recorder>(
    scene: &SceneView,
    origin: Vec3,
    dir: Vec3,
    t_max: f32,
    any_hit: bool,
    short: bool,
    rec: &mut R,
) -> ShortHit {
    #[cfg(not(target_arch = "spirv"))]
    if !scene.alpha_masks {
        return traverse_with::<S, false, R>(scene, origin, dir, t_max, any_hit, short, rec);
    }
    traverse_with::<S, true, R>(scene, origin, dir, t_max, any_hit, short, rec)
}

#[inline]
fn traverse_with<const S: usize, const MASKS: bool, R: Recorder>(
    scene: &SceneView,
    origin: Vec3,
    dir: Vec3,
    t_max: f32,
    any_hit: bool,
    short: bool,
    rec: &mut R,
) -> ShortHit {
    let mut best = Hit::miss(t_max);
    let mut restarts = 0u32;
    let ray = match ray_start(scene, origin, dir, t_max) {
        Some(ray) if S > 0 => ray,
        _ => return ShortHit { hit: best, restarts },
    };
    let (dir, inv, t_enter, t_exit) = (ray.dir, ray.inv, ray.t_enter, ray.t_exit);
    let shear = RayShear::new(origin, dir);
    let mut short = short;
    // The ring: `top` is its next free slot, and `count` entries below it are live.
    let mut ring = [StackEntry { node: 0, t_min: 0.0, t_max: 0.0 }; S];
    let mut top = 0usize;
    let mut count = 0usize;
    let mut dropped = false;
    // The nearest entry dropped since the last restart: the traversal restarts there.
    let mut drop_min = f32::MAX;
    let mut restart_at = t_enter;
    // The full stack and its pointer.
    let mut stack = Stack::new();
    let mut sp = 0usize;
    let (mut t0, mut t1) = (t_enter, t_exit);
    let mut node = 0u32;
    let (mut nodes, mut tests) = (0u32, 0u32);
    loop {
        nodes += 1;
        rec.node(node);
        let n = scene.nodes[node as usize];
        if !n.is_leaf() {
            let step = descend(n, node, origin, dir, inv, t0, t1);
            node = step.next;
            t1 = step.t1;
            if step.push & short {
                if count == S {
                    // The ring is full: the slot at `top` holds the oldest entry, dropped now.
                    let old = ring[top].t_min;
                    drop_min = if old < drop_min { old } else { drop_min };
                }
                ring[top] = step.far;
                top = if top + 1 == S { 0 } else { top + 1 };
                if count == S {
                    dropped = true;
                } else {
                    count += 1;
                }
            } else if step.push & (sp < STACK_SIZE) {
                // The builder bounds depth by KD_MAX_DEPTH, so the full stack cannot overflow
                // on a validated tree; the guard only keeps a corrupt tree from writing out of
                // bounds.
                stack.set(sp, step.far);
                sp += 1;
            }
            continue;
        }
        let done = test_leaf::<MASKS>(scene, &shear, n, &mut best, &mut tests, any_hit);
        // Pop the nearest entry that may still hold a closer hit. Entries pushed for a ray lying
        // in a split plane start where the traversal already is, so neither stack is sorted by
        // distance: every entry is checked, none is assumed culled by the one above it.
        let mut found = false;
        while short & (count > 0) & !found & !done {
            top = if top == 0 { S - 1 } else { top - 1 };
            count -= 1;
            let e = ring[top];
            if may_hold_closer(e.t_min, best.t) {
                node = e.node;
                t0 = e.t_min;
                t1 = e.t_max;
                found = true;
            }
        }
        while !short & (sp > 0) & !found & !done {
            sp -= 1;
            let e = stack.get(sp);
            if may_hold_closer(e.t_min, best.t) {
                node = e.node;
                t0 = e.t_min;
                t1 = e.t_max;
                found = true;
            }
        }
        if found {
            continue;
        }
        if done | !short {
            break;
        }
        let more = dropped & may_hold_closer(drop_min, best.t);
        if !more {
            break;
        }
        if drop_min > restart_at {
            // Restart from the root at the nearest dropped entry: everything before it has
            // been visited.
            restart_at = drop_min;
            t0 = restart_at;
            top = 0;
            count = 0;
            dropped = false;
            drop_min = f32::MAX;
        } else {
            // No progress possible (a ray lying in split planes needs both halves over the same
            // interval, more than the ring holds): start again with the full stack, counted as
            // a restart; the work so far stays counted.
            short = false;
            best = Hit::miss(t_max);
            t0 = t_enter;
        }
        t1 = t_exit;
        node = 0;
        restarts += 1;
    }
    best.nodes = nodes;
    best.tests = tests;
    ShortHit { hit: best, restarts }
}
