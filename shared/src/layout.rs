//! Buffer layouts shared by the host, the CPU renderer and the GPU kernel.
//!
//! Every struct is `#[repr(C)]`, made of `u32`, `f32` and `Vec4` only (no `bool`, no `Vec3`: a
//! 12-byte stride is not a valid storage-buffer array stride), and `Pod` on the host so it uploads
//! with `bytemuck::cast_slice`. Enums travel as a tag plus an index, never as pointers.
use crate::glam::Vec4;

/// A triangle's three vertices in world space. The `w` components of v0, v1, v2 hold its unit
/// geometric normal (`triangle::unit_normal`, stored by the host when it compiles a scene:
/// `Triangle::with_unit_normal`), so shading reads it instead of a square root and a division
/// per vertex; every intersection test reads only `xyz`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(bytemuck::Pod, bytemuck::Zeroable))]
pub struct Triangle {
    pub v0: Vec4,
    pub v1: Vec4,
    pub v2: Vec4,
}

/// Triangles tested together by the CPU's leaf test (`triangle::RayShear::intersect_block`):
/// eight, one per lane of an AVX register (two SSE registers where AVX is missing).
pub const BLOCK_WIDTH: u32 = 8;

/// Children per node of the CPU path's wide BVH (`wide_bvh`): one per lane of an AVX register,
/// as many as a leaf block holds triangles.
pub const WIDE_WIDTH: usize = BLOCK_WIDTH as usize;
/// A wide child reference with this bit set is a leaf: bits 28..31 hold its triangle count less
/// one, bits 0..28 its block (`WideNode::leaf_ref`). Without it, the child is a node index.
pub const WIDE_LEAF_BIT: u32 = 1 << 31;
/// Blocks a wide BVH may hold: a leaf's block index has 28 bits.
pub const WIDE_MAX_BLOCKS: u32 = 1 << 28;
/// Levels of wide nodes the builder may make (its binary tree stays below 48 + log2 of the
/// triangle count, `host::bvh`); the traversal's stack is sized for them.
pub const WIDE_MAX_DEPTH: usize = 96;

/// One node of the CPU path's wide BVH: the boxes of its children, lower corners in
/// `bounds[0..3]` (x, y, z), upper in `bounds[3..6]`, a lane per child, and the children's
/// references. An unused lane has the empty box (lower +∞, upper −∞), which no ray enters.
/// Aligned for AVX loads; 224 bytes. The GPU never reads it.
#[cfg(not(target_arch = "spirv"))]
#[repr(C, align(32))]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct WideNode {
    pub bounds: [[f32; WIDE_WIDTH]; 6],
    pub child: [u32; WIDE_WIDTH],
}

#[cfg(not(target_arch = "spirv"))]
impl WideNode {
    /// A node with every lane empty.
    pub fn empty() -> Self {
        let mut bounds = [[f32::INFINITY; WIDE_WIDTH]; 6];
        for b in &mut bounds[3..] {
            *b = [f32::NEG_INFINITY; WIDE_WIDTH];
        }
        Self { bounds, child: [0; WIDE_WIDTH] }
    }

    /// The reference to leaf block `block` with `count` (1..=8) triangles.
    #[inline]
    pub fn leaf_ref(block: u32, count: u32) -> u32 {
        WIDE_LEAF_BIT | ((count - 1) << 28) | block
    }

    /// The block and triangle count of leaf reference `r` (`leaf_ref`'s inverse).
    #[inline]
    pub fn leaf_of(r: u32) -> (u32, u32) {
        (r & (WIDE_MAX_BLOCKS - 1), ((r >> 28) & 7) + 1)
    }
}

/// `BLOCK_WIDTH` consecutive entries of the leaf index list, transposed so that one SIMD lane
/// holds one triangle: `v[3·j + a][lane]` holds axis `a` (0 = x) of vertex `j`. Block `k` holds
/// the triangles of index entries `8k .. 8k + 8`; the builders start every leaf at a multiple of
/// eight, so a leaf of up to eight triangles is one block test. Indexing by axis is an address
/// offset, so the per-ray axis permutation of the watertight test needs no selects. Aligned to
/// the 32 bytes of an AVX load on the CPU; the GPU never reads it.
#[repr(C)]
#[cfg_attr(not(target_arch = "spirv"), repr(align(32)))]
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(bytemuck::Pod, bytemuck::Zeroable))]
pub struct TriBlock {
    pub v: [[f32; BLOCK_WIDTH as usize]; 9],
}

impl Default for TriBlock {
    #[inline]
    fn default() -> Self {
        Self { v: [[0.0; BLOCK_WIDTH as usize]; 9] }
    }
}

impl TriBlock {
    /// Puts `t` into lane `lane` (0..BLOCK_WIDTH).
    #[cfg(not(target_arch = "spirv"))]
    #[inline]
    pub fn set_lane(&mut self, lane: usize, t: &Triangle) {
        let verts = [t.v0, t.v1, t.v2];
        let mut j = 0;
        while j < 3 {
            self.v[3 * j][lane] = verts[j].x;
            self.v[3 * j + 1][lane] = verts[j].y;
            self.v[3 * j + 2][lane] = verts[j].z;
            j += 1;
        }
    }
}

/// Marks a triangle that is not a light.
pub const NO_LIGHT: u32 = u32::MAX;
/// Marks a ray that hit nothing.
pub const NO_HIT: u32 = u32::MAX;

/// What a triangle is made of and, if it emits, which light it is.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(bytemuck::Pod, bytemuck::Zeroable))]
pub struct TriangleInfo {
    pub material: u32,
    /// Index into the light table, or `NO_LIGHT`.
    pub light: u32,
}

/// Material kinds (the tag of the tag + index dispatch, `material`).
/// Lambertian reflection of `albedo`.
pub const MATERIAL_DIFFUSE: u32 = 0;
/// A conductor: complex index of refraction `eta` + i·`k` per channel, smooth (`params.x`, the
/// GGX α, is 0) or rough.
pub const MATERIAL_CONDUCTOR: u32 = 1;
/// A dielectric of index of refraction `params.y` inside (the counter-clockwise side is outside,
/// index 1), smooth or rough (GGX α `params.x`).
pub const MATERIAL_DIELECTRIC: u32 = 2;
/// Plastic: a diffuse base `albedo` under a dielectric coating of index `params.y`, smooth
/// (`params.x` = 0) or rough (GGX α `params.x`, with the coating's transmittance table at
/// `table`); `params.z`, `params.w`: the base's constant factors (`material::plastic_scale`, or
/// the host's from the table for a rough coating).
pub const MATERIAL_PLASTIC: u32 = 3;
/// The glTF metallic-roughness model: base colour `albedo`, `params` = (GGX α, index of
/// refraction, metallic, transmission).
pub const MATERIAL_PRINCIPLED: u32 = 4;

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(bytemuck::Pod, bytemuck::Zeroable))]
pub struct Material {
    pub kind: u32,
    /// A rough plastic's coating table (`material::rough_plastic_transmittance`): its first word
    /// in the texture buffer (`binding::TEXTURES`), after the textures; 0 for every other
    /// material.
    pub table: u32,
    /// How the alpha mask (`TEXTURE_ALPHA`) cuts: `ALPHA_CUT` or `ALPHA_BLEND`.
    pub alpha_mode: u32,
    pub _pad: u32,
    /// Diffuse albedo (MTL `Kd`), linear RGB in `xyz`.
    pub albedo: Vec4,
    /// Emitted radiance from the front (counter-clockwise) side (MTL `Ke`), linear RGB in `xyz`.
    pub emission: Vec4,
    /// `x`: GGX roughness α (0: smooth); `y`: the index of refraction inside (dielectric, plastic
    /// coating, principled); `z`: metallic and `w`: transmission (principled).
    pub params: Vec4,
    /// Conductor: the real part of the complex index of refraction per channel, in `xyz`.
    /// Principled: the clear coat's factor in `x` and its GGX α in `y`; any kind: a normal
    /// map's scale in `w`.
    pub eta: Vec4,
    /// Conductor: the imaginary part (absorption), in `xyz`.
    pub k: Vec4,
    /// Texture maps by slot (`TEXTURE_ALBEDO` … `TEXTURE_METALLIC`): `NO_TEXTURE`, or 1 + the
    /// texture's index in the texture table (`texture`). `surface::resolve` replaces the
    /// constant a slot covers with the texture's value at the hit before any BSDF sees it.
    pub textures: [u32; 8],
}

/// A texture slot that holds no texture. Zero, so that a `Material` made with `Default` or
/// zeroed bytes has no textures.
pub const NO_TEXTURE: u32 = 0;
/// Slot of the texture that replaces `albedo.xyz` (MTL `map_Kd`, a scene file's `albedo_texture`).
pub const TEXTURE_ALBEDO: usize = 0;
/// Slot of the alpha mask (MTL `map_d`): a hit where its value is below `ALPHA_CUTOFF` does not
/// count.
pub const TEXTURE_ALPHA: usize = 1;
/// Slot of the texture that replaces `emission.xyz` (MTL `map_Ke`).
pub const TEXTURE_EMISSION: usize = 2;
/// Slot of the perceptual roughness r (MTL `map_Pr`): `params.x`, the GGX α, becomes r².
pub const TEXTURE_ROUGHNESS: usize = 3;
/// Slot of the metallic weight (MTL `map_Pm`): replaces `params.z`.
pub const TEXTURE_METALLIC: usize = 4;
/// Slot of a tangent-space normal map (glTF `normalTexture`, linear RGB: x, y, z = 2c − 1, +y
/// toward increasing v): it bends the shading normal (`surface::shading_normal`) in the tangent
/// frame of the triangle's texture coordinates; `eta.w` holds its scale (x and y are scaled).
pub const TEXTURE_NORMAL: usize = 5;
/// Slot of a principled material's clear coat factor (glTF `clearcoatTexture`'s R channel times
/// `clearcoatFactor`): replaces `eta.x`.
pub const TEXTURE_CLEARCOAT: usize = 6;
/// Alpha below this cuts the surface out (the usual alpha-test threshold).
pub const ALPHA_CUTOFF: f32 = 0.5;
/// `Material::alpha_mode`: the mask cuts where it is below `ALPHA_CUTOFF`.
pub const ALPHA_CUT: u32 = 0;
/// `Material::alpha_mode`: stochastic transparency (glTF `BLEND`): a ray passes a hit with
/// probability 1 − alpha, so that on average the surface covers alpha of what is behind it.
pub const ALPHA_BLEND: u32 = 1;

/// A triangle's vertex attributes (OBJ `vn` and `vt`), in the order of its vertices v0, v1, v2:
/// unit shading normals in the `xyz` of `n0`, `n1`, `n2` (all zero: the triangle has none and
/// shades with its flat normal), texture coordinates (u in the `w` of `n0`, `n1`, `n2`, v in
/// `uv_v.xyz`; all zero when the mesh gives none). One entry per triangle, or an empty buffer
/// for a scene with no attributes at all (`surface` reads zeros for a triangle beyond it).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(bytemuck::Pod, bytemuck::Zeroable))]
pub struct TriangleAttributes {
    pub n0: Vec4,
    pub n1: Vec4,
    pub n2: Vec4,
    /// v of v0, v1, v2 in `xyz`; `w` unused (0).
    pub uv_v: Vec4,
}

/// One entry of the texture table at the start of the texture buffer (four words per texture,
/// `texture::info`): where its texels start (in words from the buffer's start), its size, and
/// its format and wrap mode (`TEXTURE_*` flags).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(not(target_arch = "spirv"), derive(bytemuck::Pod, bytemuck::Zeroable))]
pub struct TextureInfo {
    pub offset: u32,
    pub width: u32,
    pub height: u32,
    pub flags: u32,
}

/// `TextureInfo::flags`: one f16 channel per texel, two texels per word (data textures:
/// roughness, metallic, alpha); without it, RGBA as four f16 in two words (colour textures).
pub const TEXTURE_ONE_CHANNEL: u32 = 1;
/// `TextureInfo::flags`: clamp coordinates to the edge instead of repeating the image.
pub const TEXTURE_CLAMP: u32 = 2;

/// `Light::triangle` of an entry that is not a triangle: bit 31 set, the rest the emitter's first
/// word in the texture buffer (`binding::TEXTURES`). With `LIGHT_ENVIRONMENT_BIT` also set it is
/// the environment map (`environment`), otherwise a punctual light (`PunctualLight`, `punctual`).
pub const LIGHT_NOT_TRIANGLE: u32 = 1 << 31;
/// See `LIGHT_NOT_TRIANGLE`.
pub const LIGHT_ENVIRONMENT_BIT: u32 = 1 << 30;
/// The word-offset bits of a `LIGHT_NOT_TRIANGLE` entry.
pub const LIGHT_OFFSET_MASK: u32 = (1 << 30) - 1;
/// `RenderParams::environment_map` when the scene has no environment map (zero, so that
/// default parameters have none).
pub const NO_ENVIRONMENT_MAP: u32 = 0;

/// Punctual light kinds (`PunctualLight::kind`), glTF `KHR_lights_punctual`.
pub const PUNCTUAL_POINT: u32 = 0;
pub const PUNCTUAL_SPOT: u32 = 1;
pub const PUNCTUAL_DIRECTIONAL: u32 = 2;

/// A point, spot or directional light as the integrator reads it: 16 words in the texture
/// buffer after the textures (`punctual::load`), found through its light-table entry
/// (`LIGHT_NOT_TRIANGLE | offset`). Delta lights: sampled by next-event estimation only.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(bytemuck::Pod, bytemuck::Zeroable))]
pub struct PunctualLight {
    /// Position (point, spot), in the scene's local frame.
    pub position: [f32; 3],
    pub kind: u32,
    /// Unit direction the light travels (spot axis, directional), world space.
    pub direction: [f32; 3],
    pub _pad0: u32,
    /// Colour × intensity: candela (point, spot) or lux (directional), linear RGB.
    pub intensity: [f32; 3],
    pub _pad1: u32,
    /// Spot cone (glTF): attenuation = clamp(cos·scale + offset, 0, 1)², scale =
    /// 1 / max(0.001, cos inner − cos outer), offset = −cos outer · scale; 0 and 1 otherwise.
    pub cone_scale: f32,
    pub cone_offset: f32,
    pub _pad2: [u32; 2],
}

/// One emitter in the light-selection table: an emissive triangle, or (`LIGHT_NOT_TRIANGLE`) the
/// environment map or a punctual light; one distribution by power over all of them.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(bytemuck::Pod, bytemuck::Zeroable))]
pub struct Light {
    pub triangle: u32,
    /// Probability of picking this light.
    pub pmf: f32,
    /// Sum of `pmf` over this light and all before it; the last entry is 1.
    pub cdf: f32,
    pub area: f32,
}

/// A k-d tree node in 8 bytes (pbrt-v3 §4.4 layout).
///
/// Interior: `a` is the split position's f32 bits, `b` is `axis | above_child << 2`; the below
/// child is the next node in the array. Leaf: `a` is the first index into the triangle index
/// list, `b` is `3 | count << 2`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(not(target_arch = "spirv"), derive(bytemuck::Pod, bytemuck::Zeroable))]
pub struct KdNode {
    pub a: u32,
    pub b: u32,
}

/// Deepest tree the traversal stack can hold; builders must not exceed it.
pub const KD_MAX_DEPTH: u32 = 40;

impl KdNode {
    #[inline]
    pub fn interior(axis: u32, split: f32, above_child: u32) -> Self {
        Self { a: split.to_bits(), b: axis | (above_child << 2) }
    }
    #[inline]
    pub fn leaf(first_index: u32, count: u32) -> Self {
        Self { a: first_index, b: 3 | (count << 2) }
    }
    #[inline]
    pub fn is_leaf(self) -> bool {
        (self.b & 3) == 3
    }
    #[inline]
    pub fn axis(self) -> u32 {
        self.b & 3
    }
    #[inline]
    pub fn split(self) -> f32 {
        f32::from_bits(self.a)
    }
    #[inline]
    pub fn above_child(self) -> u32 {
        self.b >> 2
    }
    #[inline]
    pub fn first_index(self) -> u32 {
        self.a
    }
    #[inline]
    pub fn count(self) -> u32 {
        self.b >> 2
    }
}

/// Everything a render pass needs besides the scene buffers. Uniform-buffer friendly: Vec4s
/// first, then u32/f32 in groups of four.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(bytemuck::Pod, bytemuck::Zeroable))]
pub struct RenderParams {
    /// Camera position.
    pub eye: Vec4,
    /// Right vector scaled by tan(fov/2)·aspect.
    pub right: Vec4,
    /// Up vector scaled by tan(fov/2).
    pub up: Vec4,
    /// Unit view direction.
    pub forward: Vec4,
    /// Scene bounds (the k-d root's box).
    pub bounds_min: Vec4,
    pub bounds_max: Vec4,
    /// Radiance of rays that leave the scene.
    pub environment: Vec4,
    pub width: u32,
    pub height: u32,
    /// First sample index of this pass and number of samples it adds per pixel.
    pub sample_start: u32,
    pub sample_count: u32,
    pub seed: u32,
    /// Indirect bounces: 0 is direct light only.
    pub max_bounces: u32,
    /// Bounce from which Russian roulette may end a path.
    pub rr_start: u32,
    pub light_count: u32,
    /// 1 / width and 1 / height, computed once on the host so both devices multiply.
    pub inv_width: f32,
    pub inv_height: f32,
    /// `TRAVERSAL_FULL_STACK`, `TRAVERSAL_SHORT_STACK` or (the CPU only) `TRAVERSAL_WIDE_BVH`.
    pub traversal: u32,
    /// What the image holds: `AOV_RADIANCE` or `AOV_COST`.
    pub aov: u32,
    /// Batches one workgroup of the persistent kernel takes at most in one dispatch.
    pub persistent_rounds: u32,
    /// `rng::SAMPLER_SOBOL` or `rng::SAMPLER_INDEPENDENT`.
    pub sampler: u32,
    /// Entries of the live-pixel list (`render_list`; adaptive sampling).
    pub live_count: u32,
    /// 1 + the environment map's first word in the texture buffer (`environment`), or
    /// `NO_ENVIRONMENT_MAP`.
    pub environment_map: u32,
    /// 1: light subpaths connect to the eye vertices (`features::FEATURE_CONNECT`); the host
    /// sets it only where `features::connection_applies`.
    pub connect: u32,
    /// 1: the connections draw their light vertices from the pool of light subpaths shared by
    /// all pixels (`connection::connect_pooled`, `SceneView::light_pool`); 0: each sample
    /// traces its own (`connection::connect`).
    pub light_pool: u32,
    /// The block of samples whose pool starts the pool buffer (`binding::POOL`): the first
    /// block a pass's samples draw from, or (`trace_pool`) the first one it traces.
    pub pool_first_block: u32,
    /// To a multiple of 16 bytes (scalars: a uniform block's arrays would need a 16-byte stride).
    pub _pad2: u32,
}

/// k-d traversal with a stack as deep as the tree (`kdtree`).
pub const TRAVERSAL_FULL_STACK: u32 = 0;
/// k-d traversal with a `short_stack::SHORT_STACK`-entry stack and restart (`short_stack`).
pub const TRAVERSAL_SHORT_STACK: u32 = 1;
/// The CPU's eight-wide BVH (`wide_bvh`); a GPU never gets it.
pub const TRAVERSAL_WIDE_BVH: u32 = 2;
/// `RayQuery::flags`: traverse the CPU's eight-wide BVH (`TRAVERSAL_WIDE_BVH`).
pub const RAY_WIDE_BVH: u32 = 8;

/// The image is radiance.
pub const AOV_RADIANCE: u32 = 0;
/// The image is the camera ray's traversal work: k-d nodes visited in `x`, triangles tested in
/// `y`, restarts in `z`.
pub const AOV_COST: u32 = 1;
/// The image is the first hit's albedo (`material::albedo`), black where the camera ray misses.
pub const AOV_ALBEDO: u32 = 2;
/// The image is the first hit's shading normal, turned toward the camera, in world space.
pub const AOV_NORMAL: u32 = 3;

/// `RayQuery::flags`: stop at the first hit found (a shadow or ambient-occlusion ray).
pub const RAY_ANY_HIT: u32 = 1;
/// `RayQuery::flags`: traverse with the short stack instead of the full one.
pub const RAY_SHORT_STACK: u32 = 2;
/// `RayQuery::flags`: test hits against alpha masks (`surface::cut_out`); set by the host for a
/// scene that has masks, so ray batches of other scenes skip the material lookup per hit.
pub const RAY_ALPHA_MASKS: u32 = 4;

/// One ray of a batch cast without shading: the ray-casting kernel, the CPU ≡ GPU traversal
/// check and the rays/s benchmarks read these.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(bytemuck::Pod, bytemuck::Zeroable))]
pub struct RayQuery {
    /// Origin in `xyz`; `w` unused.
    pub origin: Vec4,
    /// Direction in `xyz` (need not be unit); `w` unused.
    pub dir: Vec4,
    /// Hits count only with t in (0, t_max), t in units of `dir`.
    pub t_max: f32,
    pub flags: u32,
    pub _pad: [u32; 2],
}

/// What casting a `RayQuery` found, with the traversal's work.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(bytemuck::Pod, bytemuck::Zeroable))]
pub struct RayResult {
    /// Hit distance, or the query's `t_max` on a miss.
    pub t: f32,
    /// Triangle hit, or `NO_HIT`.
    pub triangle: u32,
    /// k-d nodes visited and triangles tested.
    pub nodes: u32,
    pub tests: u32,
    /// Restarts from the root (short-stack traversal only).
    pub restarts: u32,
    pub _pad: [u32; 3],
}

/// Group 0 of every kernel entry point: each buffer's binding. rust-gpu's `#[spirv(binding = N)]`
/// takes integer literals only, so `kernel/src/lib.rs` writes these numbers out; the host's test
/// `kernel_bindings_match_the_layout` reads the kernel's source and checks every one against
/// this table (and the workgroup sizes below).
pub mod binding {
    /// The pass's `RenderParams` (read-only). A storage buffer, not a uniform one: lavapipe
    /// compiles a shader again, whole, for each new set of values of the uniforms that steer its
    /// control flow (its "inlined uniforms"), so uniform parameters cost a compile of tens of
    /// seconds for every render, pass and seed that changes them.
    pub const PARAMS: u32 = 0;
    pub const NODES: u32 = 1;
    pub const INDICES: u32 = 2;
    pub const TRIANGLES: u32 = 3;
    pub const INFO: u32 = 4;
    pub const MATERIALS: u32 = 5;
    pub const LIGHTS: u32 = 6;
    pub const ACCUM: u32 = 7;
    pub const PRIMARY: u32 = 8;
    /// The rays of `cast_rays` (read-only).
    pub const RAYS: u32 = 9;
    pub const RESULTS: u32 = 10;
    /// The persistent kernel's work counter.
    pub const QUEUE: u32 = 11;
    /// Running sums of squared radiance (per-pixel variance).
    pub const ACCUM_SQ: u32 = 12;
    /// The CPU leaf test's triangle blocks (read-only; a placeholder on the GPU).
    pub const BLOCKS: u32 = 13;
    /// Adaptive sampling's list of live pixels and their sample ranges (read-only).
    pub const LIVE: u32 = 14;
    /// Per-triangle vertex normals and texture coordinates (`TriangleAttributes`, read-only).
    pub const ATTRIBUTES: u32 = 15;
    /// The texture table and texels (`texture`), then the rough plastics' coating tables
    /// (`Material::table`), read-only.
    pub const TEXTURES: u32 = 16;
    /// The pools of light subpaths of the blocks a pass's samples draw from
    /// (`connection::LightPool`), written by `trace_pool` and read by the render entry points.
    pub const POOL: u32 = 17;
    /// Bindings in all, every one a storage buffer.
    pub const COUNT: u32 = 18;
    /// The bindings the kernel writes; every other binding is read-only.
    pub const WRITABLE: [u32; 6] = [ACCUM, PRIMARY, RESULTS, QUEUE, ACCUM_SQ, POOL];
}

/// The render kernel's workgroup is `RENDER_GROUP_SIDE`² invocations, one per pixel.
pub const RENDER_GROUP_SIDE: u32 = 8;
/// The persistent kernel's workgroup size, which is also the batch of pixels one workgroup takes
/// from the queue.
pub const PERSISTENT_GROUP: u32 = 64;
/// The live-pixel list kernel's workgroup size (adaptive sampling).
pub const LIST_GROUP: u32 = 64;
/// The ray-casting kernel's workgroup size.
pub const CAST_GROUP: u32 = 64;
/// The pool-tracing kernel's workgroup size (`trace_pool`), a divisor of `POOL_SLOTS`.
pub const POOL_GROUP: u32 = 64;
