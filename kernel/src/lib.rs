//! rust-gpu entry points. Each one only unpacks its invocation id and buffers and calls `shared`.
//!
//! Every entry point declares the same bindings of group 0 (the host creates one explicit layout
//! for all of them); an entry point that does not touch a buffer still names it. The binding
//! numbers and workgroup sizes are `shared::layout::binding` and its group sizes, written out as
//! literals because `#[spirv(...)]` takes no constants; the host's test
//! `kernel_bindings_match_the_layout` checks them. Every binding is a storage buffer, the
//! parameters too (`shared::layout::binding::PARAMS` says why).
//!
//! The render entry points take the integrator's variant as specialisation constants (ids and
//! defaults: `shared::features::spec_id`, `FEATURES_ALL`, `FROM_PARAMS`; literals for the same
//! reason, checked by the same test): the defaults give the generic code, and a pipeline created
//! with other values is that variant, compiled without what its feature set leaves out.
#![no_std]

use shared::connection::{pool_buffer_record, store_pool_record, POOL_SLOTS};
use shared::features::{Variant, FEATURE_ALPHA_MASKS};
use shared::glam::{UVec3, UVec4, Vec4};
use shared::integrator::{render_pixel, render_samples};
use shared::layout::{
    KdNode, Light, Material, RayQuery, RayResult, RenderParams, TriBlock, Triangle, TriangleAttributes, TriangleInfo,
    LIST_GROUP, PERSISTENT_GROUP, POOL_GROUP,
};
use shared::raycast::cast_ray;
use shared::scene::SceneView;
use spirv_std::arch::{atomic_i_add, workgroup_memory_barrier_with_group_sync};
use spirv_std::memory::{Scope, Semantics};
use spirv_std::spirv;

/// The scene's buffers as the integrator's view, testing alpha masks only where the variant has
/// them (`SceneView::alpha_masks`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn view<'a>(
    params: &RenderParams,
    nodes: &'a [KdNode],
    indices: &'a [u32],
    blocks: &'a [TriBlock],
    triangles: &'a [Triangle],
    info: &'a [TriangleInfo],
    materials: &'a [Material],
    lights: &'a [Light],
    attributes: &'a [TriangleAttributes],
    textures: &'a [u32],
    pool: &'a [f32],
    v: Variant,
) -> SceneView<'a> {
    let mut scene =
        SceneView::new(params, nodes, indices, blocks, triangles, info, materials, lights, attributes, textures, pool);
    scene.alpha_masks = v.has(FEATURE_ALPHA_MASKS);
    scene
}

/// One invocation per pixel: adds this pass's samples to the pixel's running sum.
#[spirv(compute(threads(8, 8, 1)))]
#[allow(clippy::too_many_arguments)]
pub fn render_pass(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(spec_constant(id = 0, default = 32767))] features: u32,
    #[spirv(spec_constant(id = 1, default = 4294967295))] max_bounces: u32,
    #[spirv(spec_constant(id = 2, default = 4294967295))] rr_start: u32,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &RenderParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] nodes: &[KdNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] indices: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] triangles: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] info: &[TriangleInfo],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] materials: &[Material],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] lights: &[Light],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 13)] blocks: &[TriBlock],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 15)] attributes: &[TriangleAttributes],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 16)] textures: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] accum: &mut [Vec4],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] primary: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 12)] accum_sq: &mut [Vec4],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 17)] pool: &mut [f32],
) {
    if (id.x >= params.width) | (id.y >= params.height) {
        return;
    }
    let v = Variant::from_spec(features, max_bounces, rr_start, params);
    let scene = view(params, nodes, indices, blocks, triangles, info, materials, lights, attributes, textures, pool, v);
    let pixel = (id.y * params.width + id.x) as usize;
    render_pixel(&scene, params, v, id.x, id.y, &mut accum[pixel], &mut accum_sq[pixel], &mut primary[pixel]);
}

/// Persistent threads (Aila & Laine 2009): a fixed grid of workgroups, each taking batches of
/// `PERSISTENT_GROUP` pixels from a global atomic counter until every pixel is done, so no
/// workgroup idles while others still trace long paths. One invocation fetches for its
/// workgroup and shares the batch through workgroup memory; the loop's exit depends only on that
/// shared value, so the barriers stay in uniform control flow. A workgroup takes at most
/// `persistent_rounds` batches; the host launches enough workgroups that the queue drains.
#[spirv(compute(threads(64, 1, 1)))]
#[allow(clippy::too_many_arguments)]
pub fn render_persistent(
    #[spirv(local_invocation_index)] lane: u32,
    #[spirv(workgroup)] batch: &mut u32,
    #[spirv(spec_constant(id = 0, default = 32767))] features: u32,
    #[spirv(spec_constant(id = 1, default = 4294967295))] max_bounces: u32,
    #[spirv(spec_constant(id = 2, default = 4294967295))] rr_start: u32,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &RenderParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] nodes: &[KdNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] indices: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] triangles: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] info: &[TriangleInfo],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] materials: &[Material],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] lights: &[Light],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 13)] blocks: &[TriBlock],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 15)] attributes: &[TriangleAttributes],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 16)] textures: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] accum: &mut [Vec4],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] primary: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 11)] queue: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 12)] accum_sq: &mut [Vec4],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 17)] pool: &mut [f32],
) {
    let v = Variant::from_spec(features, max_bounces, rr_start, params);
    let scene = view(params, nodes, indices, blocks, triangles, info, materials, lights, attributes, textures, pool, v);
    let total = params.width * params.height;
    let mut running = true;
    let mut round = 0;
    while running & (round < params.persistent_rounds) {
        round += 1;
        if lane == 0 {
            // QueueFamily scope: Device scope needs a capability naga rejects.
            *batch = unsafe {
                atomic_i_add::<u32, { Scope::QueueFamily as u32 }, { Semantics::NONE.bits() }>(
                    &mut queue[0],
                    PERSISTENT_GROUP,
                )
            };
        }
        workgroup_memory_barrier_with_group_sync();
        let base = *batch;
        // Everyone has read the batch before lane 0 may overwrite it in the next round.
        workgroup_memory_barrier_with_group_sync();
        if base >= total {
            running = false;
        } else {
            let pixel = base + lane;
            if pixel < total {
                let (x, y) = (pixel % params.width, pixel / params.width);
                let i = pixel as usize;
                render_pixel(&scene, params, v, x, y, &mut accum[i], &mut accum_sq[i], &mut primary[i]);
            }
        }
    }
}

/// Adaptive sampling: one invocation per entry of a list of live pixels, entry `i` naming a
/// pixel (`x`), the first sample it adds in this pass (`y`) and how many (`z`). The list has
/// `params.live_count` entries; the grid is two-dimensional so that a list longer than one
/// dimension's 65,535 workgroups still fits in one dispatch.
#[spirv(compute(threads(64, 1, 1)))]
#[allow(clippy::too_many_arguments)]
pub fn render_list(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(spec_constant(id = 0, default = 32767))] features: u32,
    #[spirv(spec_constant(id = 1, default = 4294967295))] max_bounces: u32,
    #[spirv(spec_constant(id = 2, default = 4294967295))] rr_start: u32,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &RenderParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] nodes: &[KdNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] indices: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] triangles: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] info: &[TriangleInfo],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] materials: &[Material],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] lights: &[Light],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 13)] blocks: &[TriBlock],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 15)] attributes: &[TriangleAttributes],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 16)] textures: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] accum: &mut [Vec4],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] primary: &mut [u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 12)] accum_sq: &mut [Vec4],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 14)] live: &[UVec4],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 17)] pool: &mut [f32],
) {
    let i = id.y * groups.x * LIST_GROUP + id.x;
    if i >= params.live_count {
        return;
    }
    let v = Variant::from_spec(features, max_bounces, rr_start, params);
    let scene = view(params, nodes, indices, blocks, triangles, info, materials, lights, attributes, textures, pool, v);
    let e = live[i as usize];
    let (x, y, pixel) = (e.x % params.width, e.x / params.width, e.x as usize);
    render_samples(&scene, params, v, x, y, e.y, e.z, &mut accum[pixel], &mut accum_sq[pixel], &mut primary[pixel]);
}

/// One invocation per ray of a batch: the closest (or any) hit and the traversal's work.
#[spirv(compute(threads(64, 1, 1)))]
#[allow(clippy::too_many_arguments)]
pub fn cast_rays(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &RenderParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] nodes: &[KdNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] indices: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] triangles: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] info: &[TriangleInfo],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] materials: &[Material],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] lights: &[Light],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 13)] blocks: &[TriBlock],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 15)] attributes: &[TriangleAttributes],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 16)] textures: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] rays: &[RayQuery],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 10)] results: &mut [RayResult],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 17)] pool: &mut [f32],
) {
    let i = id.x as usize;
    if i >= rays.len() {
        return;
    }
    let scene =
        SceneView::new(params, nodes, indices, blocks, triangles, info, materials, lights, attributes, textures, pool);
    results[i] = cast_ray(&scene, &rays[i]);
}

/// One invocation per light subpath of the pools of `params.sample_count` blocks from
/// `params.pool_first_block`: traces it and stores its record (`connection::pool_buffer_record`).
/// The grid is two-dimensional, as `render_list`'s, for pools of more than 65,535 workgroups.
#[spirv(compute(threads(64, 1, 1)))]
#[allow(clippy::too_many_arguments)]
pub fn trace_pool(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(num_workgroups)] groups: UVec3,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &RenderParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] nodes: &[KdNode],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] indices: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] triangles: &[Triangle],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] info: &[TriangleInfo],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] materials: &[Material],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] lights: &[Light],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 13)] blocks: &[TriBlock],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 15)] attributes: &[TriangleAttributes],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 16)] textures: &[u32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 17)] pool: &mut [f32],
) {
    let i = id.y * groups.x * POOL_GROUP + id.x;
    if i >= params.sample_count * POOL_SLOTS {
        return;
    }
    let scene =
        SceneView::new(params, nodes, indices, blocks, triangles, info, materials, lights, attributes, textures, pool);
    let record = pool_buffer_record(&scene, params, i);
    store_pool_record(pool, i, &record);
}
