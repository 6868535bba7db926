//! k-d tree traversal: the node layout is in `layout::KdNode`, the builders live in the host.
//!
//! A stack-based front-to-back traversal (pbrt-v3 §4.4.3, Wald's thesis §7.2) with explicit
//! handling of axis-parallel rays: when a direction component is zero the ray never crosses that
//! split plane, so no `(split − o)·(1/0)` is ever formed (it would be `0·∞ = NaN` for a ray lying
//! in the plane). A ray lying exactly in a split plane visits both children, since triangles in
//! the plane may have been placed on either side.
//!
//! Termination is by culling, not by leaf exit: a node popped from the stack is skipped only when
//! its entry distance, lowered by `T_SLACK`, exceeds the closest hit so far. Together with a
//! conservative triangle placement by the builder this returns exactly the hit that testing every
//! triangle returns (`intersect_brute_force`), bit for bit, because every triangle test performs
//! the operations of `RayShear::intersect` (the CPU's eight-lane `intersect_block` lane by lane).
//!
//! A hit that its material's alpha mask cuts out (`surface::cut_out`) is no hit: the leaf test
//! skips it and goes on, so every traversal (and brute force) returns the closest hit that
//! counts, and an any-hit query stops only at one that counts.
use crate::glam::Vec3;
#[cfg(not(target_arch = "spirv"))]
use crate::layout::BLOCK_WIDTH;
use crate::layout::{KdNode, KD_MAX_DEPTH, NO_HIT};
use crate::numerics::{gamma, is_finite3, T_SLACK};
use crate::record::{NoRecord, Recorder};
use crate::scene::SceneView;
use crate::surface::cut_out;
use crate::triangle::RayShear;
use crate::vecmath::axis;

pub(crate) const STACK_SIZE: usize = KD_MAX_DEPTH as usize + 1;

/// The closest hit of a ray, or `triangle == NO_HIT`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub triangle: u32,
    /// Unnormalised barycentric weights of v0, v1, v2.
    pub u: f32,
    pub v: f32,
    pub w: f32,
    /// Traversal statistics: tree nodes visited and triangles tested for this ray.
    pub nodes: u32,
    pub tests: u32,
}

impl Hit {
    #[inline]
    pub fn miss(t_max: f32) -> Self {
        Self { t: t_max, triangle: NO_HIT, u: 0.0, v: 0.0, w: 0.0, nodes: 0, tests: 0 }
    }
    #[inline]
    pub fn is_hit(&self) -> bool {
        self.triangle != NO_HIT
    }
}

#[derive(Clone, Copy)]
pub(crate) struct StackEntry {
    pub node: u32,
    pub t_min: f32,
    pub t_max: f32,
}

/// Components below the smallest normal float become exactly zero: a GPU may flush denormals
/// while the CPU keeps them, and the traversal treats zero components as parallel to a plane.
#[inline]
pub fn flush_denormals(d: Vec3) -> Vec3 {
    Vec3::new(flush(d.x), flush(d.y), flush(d.z))
}

#[inline]
fn flush(x: f32) -> f32 {
    if x.abs() < f32::MIN_POSITIVE {
        0.0
    } else {
        x
    }
}

#[inline]
fn recip(x: f32) -> f32 {
    if x == 0.0 {
        0.0
    } else {
        1.0 / x
    }
}

/// Per-axis reciprocal direction; zero components get 0 and are never used (see module docs).
#[inline]
pub(crate) fn safe_reciprocal(d: Vec3) -> Vec3 {
    Vec3::new(recip(d.x), recip(d.y), recip(d.z))
}

/// Slab test against the scene box; `None` when the ray misses it within (t_min, t_max).
/// The exit distance is widened by 2γ(3) (pbrt-v4 `Bounds3::IntersectP`) so a triangle lying on
/// the box face is not lost to rounding.
#[inline]
pub fn clip_to_bounds(
    lo: Vec3,
    hi: Vec3,
    origin: Vec3,
    dir: Vec3,
    inv: Vec3,
    t_min: f32,
    t_max: f32,
) -> Option<(f32, f32)> {
    let mut t0 = t_min;
    let mut t1 = t_max;
    let mut a = 0;
    while a < 3 {
        let o = axis(origin, a);
        let d = axis(dir, a);
        let (l, h) = (axis(lo, a), axis(hi, a));
        if d == 0.0 {
            if (o < l) | (o > h) {
                return None;
            }
        } else {
            let i = axis(inv, a);
            let mut near = (l - o) * i;
            let mut far = (h - o) * i;
            if near > far {
                core::mem::swap(&mut near, &mut far);
            }
            far *= 1.0 + 2.0 * gamma(3);
            t0 = if near > t0 { near } else { t0 };
            t1 = if far < t1 { far } else { t1 };
            if t0 > t1 {
                return None;
            }
        }
        a += 1;
    }
    Some((t0, t1))
}

/// Whether a node the ray enters at `t_min` may still hold a hit closer than `best_t`: the cull
/// rule of both traversals (entry lowered by `T_SLACK`, see the module docs).
#[inline]
pub(crate) fn may_hold_closer(t_min: f32, best_t: f32) -> bool {
    t_min * (1.0 - T_SLACK) <= best_t
}

/// What every traversal of a ray starts from: the direction with denormals flushed, its
/// per-axis reciprocal, and the interval in which it crosses the scene box.
#[derive(Clone, Copy)]
pub(crate) struct RayStart {
    pub dir: Vec3,
    pub inv: Vec3,
    pub t_enter: f32,
    pub t_exit: f32,
}

/// The direction with denormals flushed, or `None` for a ray that cannot hit anything: a
/// non-finite origin or direction, or a zero direction. What every traversal and brute force check
/// first (`ray_in_box` then clips to the scene box; the wide BVH's root boxes stand for it).
#[inline(always)]
pub(crate) fn usable_direction(origin: Vec3, dir: Vec3) -> Option<Vec3> {
    let dir = flush_denormals(dir);
    let zero_dir = (dir.x == 0.0) & (dir.y == 0.0) & (dir.z == 0.0);
    (is_finite3(origin) & is_finite3(dir) & !zero_dir).then_some(dir)
}

/// `None` for a ray that cannot hit anything: non-finite origin or direction, zero direction, an
/// empty tree, or a ray that misses the scene box within (0, t_max).
///
/// Always inlined on the CPU, as `test_leaf`: LLVM's choice for it differed between the two
/// traversals and changed with unrelated edits.
#[cfg_attr(not(target_arch = "spirv"), inline(always))]
#[cfg_attr(target_arch = "spirv", inline)]
pub(crate) fn ray_start(scene: &SceneView, origin: Vec3, dir: Vec3, t_max: f32) -> Option<RayStart> {
    if scene.nodes.is_empty() {
        return None;
    }
    ray_in_box(scene, origin, dir, t_max)
}

/// `ray_start` for any tree: `None` for a non-finite origin or direction, a zero direction, or a
/// ray that misses the scene box within (0, t_max).
#[cfg_attr(not(target_arch = "spirv"), inline(always))]
#[cfg_attr(target_arch = "spirv", inline)]
pub(crate) fn ray_in_box(scene: &SceneView, origin: Vec3, dir: Vec3, t_max: f32) -> Option<RayStart> {
    let dir = usable_direction(origin, dir)?;
    let inv = safe_reciprocal(dir);
    let (t_enter, t_exit) = clip_to_bounds(scene.bounds_min, scene.bounds_max, origin, dir, inv, 0.0, t_max)?;
    Some(RayStart { dir, inv, t_enter, t_exit })
}

/// Tests the triangles of leaf `n` against the ray, narrowing `best`; counts the leaf's
/// triangles as tested. Returns whether an any-hit query (`any_hit`) is answered, by the first
/// triangle of the leaf's run that the ray hits. Leaf intervals do not clip the test: a hit
/// anywhere in (0, best.t) counts, which is what makes the result equal brute force.
///
/// A CPU tests `BLOCK_WIDTH` (eight) triangles at a time in SIMD lanes (`test_leaf_blocks`); a
/// GPU thread would execute the lanes one after another, so it tests the leaf's triangles one by one
/// (`test_leaf_each`). Both return the same hit and the same counts (tested against each other).
///
/// Always inlined on the CPU: left to LLVM, whether it was inlined into `traverse_with` changed
/// with unrelated edits to the traversal (a call per leaf, 0.5% of a render's instructions).
#[cfg_attr(not(target_arch = "spirv"), inline(always))]
#[cfg_attr(target_arch = "spirv", inline)]
pub(crate) fn test_leaf<const MASKS: bool>(
    scene: &SceneView,
    shear: &RayShear,
    n: KdNode,
    best: &mut Hit,
    tests: &mut u32,
    any_hit: bool,
) -> bool {
    #[cfg(target_arch = "spirv")]
    return test_leaf_each(scene, shear, n, best, tests, any_hit);
    #[cfg(not(target_arch = "spirv"))]
    return test_blocks::<MASKS>(scene, shear, n, best, tests, any_hit);
}

/// `test_leaf` one triangle at a time, in the order of the leaf's run.
#[inline]
pub fn test_leaf_each(
    scene: &SceneView,
    shear: &RayShear,
    n: KdNode,
    best: &mut Hit,
    tests: &mut u32,
    any_hit: bool,
) -> bool {
    let start = n.first_index();
    let end = start + n.count();
    *tests += n.count();
    let mut i = start;
    let mut done = false;
    while (i < end) & !done {
        let id = scene.indices[i as usize];
        if let Some(h) = shear.intersect(&scene.triangles[id as usize], 0.0, best.t) {
            // A hit its alpha mask cuts out does not count: the leaf goes on.
            if !cut_out(scene, id, h.u, h.v, h.w) {
                *best = Hit { t: h.t, triangle: id, u: h.u, v: h.v, w: h.w, nodes: 0, tests: 0 };
                done = any_hit;
            }
        }
        i += 1;
    }
    done
}

/// `test_leaf` eight triangles at a time (`TriBlock`, `RayShear::intersect_block`), whole blocks
/// without masks: the host lays the index list out so that every non-empty leaf's run starts a
/// block and the lanes after its end repeat its last triangle (`kdbuild::align_leaves` in the
/// host). A repeat hits at the same distance as the real lane before it, which wins the tie, so
/// the hit and the counts are `test_leaf_each`'s.
#[cfg(not(target_arch = "spirv"))]
#[inline]
pub fn test_leaf_blocks(
    scene: &SceneView,
    shear: &RayShear,
    n: KdNode,
    best: &mut Hit,
    tests: &mut u32,
    any_hit: bool,
) -> bool {
    test_blocks::<true>(scene, shear, n, best, tests, any_hit)
}

/// `test_leaf_blocks` with the masks' test compiled in (`MASKS`, then tested when the scene
/// view has masks) or out: a scene without masks traverses without the retest loop's code
/// (`traverse`'s variant per setting).
#[cfg(not(target_arch = "spirv"))]
#[inline(always)]
fn test_blocks<const MASKS: bool>(
    scene: &SceneView,
    shear: &RayShear,
    n: KdNode,
    best: &mut Hit,
    tests: &mut u32,
    any_hit: bool,
) -> bool {
    let start = n.first_index();
    let end = start + n.count();
    *tests += n.count();
    // An empty leaf's start need not be aligned (only non-empty runs are): it tests nothing.
    let k = start / BLOCK_WIDTH;
    let past = if start == end { k } else { end.div_ceil(BLOCK_WIDTH) };
    test_block_run::<MASKS, false>(scene, scene.blocks, scene.indices, k, past, shear, best, any_hit)
}

/// Tests blocks `k .. past` of `blocks` (lane `l` of block `b` is triangle `indices[8b + l]`),
/// narrowing `best`; the leaf test of both the k-d tree and the CPU's wide BVH (`wide_bvh`).
/// Returns whether an any-hit query is answered.
///
/// With `TIES`, a hit at exactly the closest distance so far replaces it when its triangle id is
/// lower: brute force's answer whatever order leaves come in, for blocks whose lanes hold
/// ascending ids (the wide BVH's leaves; a k-d tree keeps coincident triangles in the same leaves
/// and tests them in id order already).
#[cfg(not(target_arch = "spirv"))]
#[inline(always)]
#[allow(clippy::too_many_arguments)] // the run, the ray and the result
pub(crate) fn test_block_run<const MASKS: bool, const TIES: bool>(
    scene: &SceneView,
    blocks: &[crate::layout::TriBlock],
    indices: &[u32],
    mut k: u32,
    past: u32,
    shear: &RayShear,
    best: &mut Hit,
    any_hit: bool,
) -> bool {
    // The distance below which a hit is closer, and whether one at it may still win.
    let limit = |best: &Hit| if TIES & best.is_hit() { crate::numerics::next_float_up(best.t) } else { best.t };
    let wins = |best: &Hit, t: f32, id: u32| !TIES | (t < best.t) | (id < best.triangle);
    let mut done = false;
    if !MASKS | !scene.alpha_masks {
        // No masks: one block test per block (the loop below, without its retests).
        while (k < past) & !done {
            if let Some((lane, h)) = shear.intersect_block(&blocks[k as usize], ALL_LANES, 0.0, limit(best), any_hit) {
                let id = indices[(k * BLOCK_WIDTH + lane) as usize];
                if wins(best, h.t, id) {
                    *best = Hit { t: h.t, triangle: id, u: h.u, v: h.v, w: h.w, nodes: 0, tests: 0 };
                    done = any_hit;
                }
            }
            k += 1;
        }
        if !MASKS {
            return done;
        }
    }
    while (k < past) & !done {
        // A lane whose hit its alpha mask cuts out leaves the mask and the block is tested again:
        // the next closest (or next) lane, as `test_leaf_each` finds it.
        let mut lanes = ALL_LANES;
        while lanes != 0 {
            lanes = match shear.intersect_block(&blocks[k as usize], lanes, 0.0, limit(best), any_hit) {
                Some((lane, h)) => {
                    let id = indices[(k * BLOCK_WIDTH + lane) as usize];
                    if !wins(best, h.t, id) {
                        // A tie with a lower id already found: the later lanes' ids are higher.
                        0
                    } else if cut_out(scene, id, h.u, h.v, h.w) {
                        lanes & !(1 << lane)
                    } else {
                        *best = Hit { t: h.t, triangle: id, u: h.u, v: h.v, w: h.w, nodes: 0, tests: 0 };
                        done = any_hit;
                        0
                    }
                }
                None => 0,
            };
        }
        k += 1;
    }
    done
}

/// `intersect_block`'s lane mask for all lanes.
#[cfg(not(target_arch = "spirv"))]
const ALL_LANES: u32 = (1 << BLOCK_WIDTH) - 1;

/// The step at one interior node: the child to visit now, the end of the ray's interval in it,
/// and the far child to visit later over its own interval, if the ray reaches it (Wald's thesis
/// §7.2; a ray lying in the plane visits both children over the same interval).
#[derive(Clone, Copy)]
pub(crate) struct Descent {
    pub next: u32,
    pub t1: f32,
    pub push: bool,
    pub far: StackEntry,
}

/// Where the ray goes at interior node `n` (index `node`) over [t0, t1]. Shared by the full- and
/// the short-stack traversal, so both visit the same children with the same intervals.
#[inline]
pub(crate) fn descend(n: KdNode, node: u32, origin: Vec3, dir: Vec3, inv: Vec3, t0: f32, t1: f32) -> Descent {
    let ax = n.axis();
    let split = n.split();
    let o = axis(origin, ax);
    let d = axis(dir, ax);
    let below_first = (o < split) | ((o == split) & (d <= 0.0));
    let (first, second) = if below_first { (node + 1, n.above_child()) } else { (n.above_child(), node + 1) };
    let mut step = Descent { next: first, t1, push: false, far: StackEntry { node: second, t_min: t0, t_max: t1 } };
    if d == 0.0 {
        // Parallel to the plane: stay on the origin's side, or visit both when in it.
        step.push = o == split;
    } else {
        let t_split = (split - o) * axis(inv, ax);
        // A split beyond the interval (or behind the origin) leaves only the near child.
        if (t_split <= t1 * (1.0 + T_SLACK)) & (t_split > 0.0) {
            if t_split < t0 * (1.0 - T_SLACK) {
                step.next = second;
            } else {
                step.push = true;
                step.far.t_min = if t_split > t0 { t_split } else { t0 };
                step.t1 = if t_split < t1 { t_split } else { t1 };
            }
        }
    }
    step
}

/// The full traversal's stack. A GPU needs initialised arrays and has no memset; on the CPU,
/// zeroing all `STACK_SIZE` entries for every ray measured 2% of a render's instructions, so
/// there the slots start uninitialised and only pushed slots are read.
pub(crate) struct Stack {
    #[cfg(target_arch = "spirv")]
    slots: [StackEntry; STACK_SIZE],
    #[cfg(not(target_arch = "spirv"))]
    slots: [core::mem::MaybeUninit<StackEntry>; STACK_SIZE],
}

impl Stack {
    #[inline]
    pub(crate) fn new() -> Self {
        #[cfg(target_arch = "spirv")]
        return Self { slots: [StackEntry { node: 0, t_min: 0.0, t_max: 0.0 }; STACK_SIZE] };
        #[cfg(not(target_arch = "spirv"))]
        return Self { slots: [core::mem::MaybeUninit::uninit(); STACK_SIZE] };
    }

    #[inline]
    pub(crate) fn set(&mut self, i: usize, e: StackEntry) {
        #[cfg(target_arch = "spirv")]
        {
            self.slots[i] = e;
        }
        #[cfg(not(target_arch = "spirv"))]
        {
            self.slots[i] = core::mem::MaybeUninit::new(e);
        }
    }

    /// Slot `i`, which the traversal has `set` (it reads only below its stack pointer).
    #[inline]
    pub(crate) fn get(&self, i: usize) -> StackEntry {
        #[cfg(target_arch = "spirv")]
        return self.slots[i];
        // SAFETY: the traversal (`short_stack::traverse`) reads a slot only after pushing it:
        // every index it reads lies below the stack pointer, and every slot below the pointer
        // was written by `set`.
        #[cfg(not(target_arch = "spirv"))]
        return unsafe { self.slots[i].assume_init() };
    }
}

/// The closest hit with t in (0, t_max).
#[inline]
pub fn intersect(scene: &SceneView, origin: Vec3, dir: Vec3, t_max: f32) -> Hit {
    traverse(scene, origin, dir, t_max, false, &mut NoRecord)
}

/// Whether anything lies along the ray with t in (0, t_max).
#[inline]
pub fn occluded(scene: &SceneView, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
    occluded_hit(scene, origin, dir, t_max).is_hit()
}

/// The first hit found with t in (0, t_max), not necessarily the closest: a shadow-ray query
/// that also reports the traversal's work.
#[inline]
pub fn occluded_hit(scene: &SceneView, origin: Vec3, dir: Vec3, t_max: f32) -> Hit {
    traverse(scene, origin, dir, t_max, true, &mut NoRecord)
}

/// The closest (or any) hit with t in (0, t_max). On the CPU, a scene without alpha masks runs
/// a traversal compiled without their test (`test_blocks`); a GPU variant has it or not by its
/// specialisation constant, so it compiles one. `rec` hears of every node visited
/// (`Recorder::node`). The loop is the short stack's (`short_stack::traverse`) with the full
/// stack chosen, so that a shader that offers both stacks holds one copy of it.
#[inline]
pub(crate) fn traverse<R: Recorder>(
    scene: &SceneView,
    origin: Vec3,
    dir: Vec3,
    t_max: f32,
    any_hit: bool,
    rec: &mut R,
) -> Hit {
    crate::short_stack::traverse::<1, R>(scene, origin, dir, t_max, any_hit, false, rec).hit
}

/// Tests every triangle: the reference the tree must reproduce exactly.
pub fn intersect_brute_force(scene: &SceneView, origin: Vec3, dir: Vec3, t_max: f32) -> Hit {
    let mut best = Hit::miss(t_max);
    let Some(dir) = usable_direction(origin, dir) else { return best };
    let shear = RayShear::new(origin, dir);
    let mut id = 0;
    while id < scene.triangles.len() {
        if let Some(h) = shear.intersect(&scene.triangles[id], 0.0, best.t) {
            if !cut_out(scene, id as u32, h.u, h.v, h.w) {
                best = Hit { t: h.t, triangle: id as u32, u: h.u, v: h.v, w: h.w, nodes: 0, tests: 0 };
            }
        }
        id += 1;
    }
    best.tests = scene.triangles.len() as u32;
    best
}
