//! The scene as the integrator sees it: borrowed slices of the GPU buffers.
use crate::glam::Vec3;
use crate::layout::{KdNode, Light, Material, RenderParams, TriBlock, Triangle, TriangleAttributes, TriangleInfo};
use crate::vecmath::xyz;

#[derive(Clone, Copy)]
pub struct SceneView<'a> {
    pub nodes: &'a [KdNode],
    /// Triangle ids of all leaves, each leaf a contiguous run.
    pub indices: &'a [u32],
    /// The triangles of `indices` in blocks of `BLOCK_WIDTH` (`TriBlock`), what the CPU's leaf
    /// test reads.
    pub blocks: &'a [TriBlock],
    pub triangles: &'a [Triangle],
    pub info: &'a [TriangleInfo],
    pub materials: &'a [Material],
    /// The first `light_count` entries are real (a GPU buffer cannot be empty).
    pub lights: &'a [Light],
    pub light_count: u32,
    /// Per-triangle vertex normals and texture coordinates; may be shorter than `triangles`
    /// (empty for a scene without any): a triangle beyond it has none (`surface`).
    pub attributes: &'a [TriangleAttributes],
    /// The texture table and texels (`texture`).
    pub textures: &'a [u32],
    /// Whether hits are tested against alpha masks (`surface::cut_out`): set where the variant
    /// has `FEATURE_ALPHA_MASKS` (the kernel) or the scene has masks (the CPU); true by default,
    /// which is always correct, only slower.
    pub alpha_masks: bool,
    pub bounds_min: Vec3,
    pub bounds_max: Vec3,
    /// The CPU's eight-wide BVH over the same triangles (`wide_bvh`); empty unless the host
    /// built one.
    #[cfg(not(target_arch = "spirv"))]
    pub wide: WideView<'a>,
    /// The CPU lanes' split of the same triangles into a few large ones and a BVH over the rest
    /// (`lanes::split`); empty unless the host chose one.
    #[cfg(not(target_arch = "spirv"))]
    pub split: SplitView<'a>,
    /// The light subpaths shared by all pixels that the connections draw from
    /// (`connection::LightPool`); empty where the render does not use them.
    pub light_pool: crate::connection::LightPool<'a>,
}

impl<'a> SceneView<'a> {
    /// Binds the buffers; light count, bounds and the pool's first block travel in the render
    /// parameters.
    #[inline]
    #[allow(clippy::too_many_arguments)] // one argument per buffer binding
    pub fn new(
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
    ) -> Self {
        Self {
            nodes,
            indices,
            blocks,
            triangles,
            info,
            materials,
            lights,
            light_count: params.light_count,
            attributes,
            textures,
            alpha_masks: true,
            bounds_min: xyz(params.bounds_min),
            bounds_max: xyz(params.bounds_max),
            #[cfg(not(target_arch = "spirv"))]
            wide: WideView::default(),
            #[cfg(not(target_arch = "spirv"))]
            split: SplitView::default(),
            light_pool: crate::connection::LightPool { records: pool, first_block: params.pool_first_block },
        }
    }
}

/// The CPU path's wide BVH as its traversal reads it (`wide_bvh`): node 0 is the root (no nodes:
/// an empty scene); leaf blocks, and per block `BLOCK_WIDTH` triangle ids (lanes past a leaf's
/// count repeat its last triangle, as in the k-d tree's blocks).
#[cfg(not(target_arch = "spirv"))]
#[derive(Clone, Copy, Default)]
pub struct WideView<'a> {
    pub nodes: &'a [crate::layout::WideNode],
    pub blocks: &'a [TriBlock],
    pub indices: &'a [u32],
}

/// The scene's triangles in two parts, for the CPU's lane integrator (`lanes::split`): a few
/// large ones (`large`, copies of the triangles `large_ids` names, ids ascending) that sixteen
/// rays test at once, and a wide BVH over all the others (`rest`) whose box, `rest_min` to
/// `rest_max`, a ray must enter before it is traversed. Empty (no large triangles) where the
/// host found no split worth it.
#[cfg(not(target_arch = "spirv"))]
#[derive(Clone, Copy, Default)]
pub struct SplitView<'a> {
    pub large: &'a [Triangle],
    pub large_ids: &'a [u32],
    pub rest: WideView<'a>,
    pub rest_min: Vec3,
    pub rest_max: Vec3,
}
