//! The CPU's integrator over sixteen samples at a time (of one pixel, or of a few neighbours in
//! a row), one sample per SIMD lane.
//!
//! Mitsuba 3's LLVM backend runs a path tracer's arithmetic for a wavefront of samples in the
//! lanes of a vector register, a pixel's samples in adjacent lanes (its `SamplingIntegrator`),
//! and hands Embree the rays as packets. The scalar integrator (`crate::integrator`) runs one
//! sample at a time, and on small scenes about half of a sample's time is that arithmetic:
//! the sampler's hashes and scrambles, the camera, warps, hit points, ray offsets and MIS
//! weights. Here sixteen samples advance in lockstep, vertex by vertex: every such step is one
//! instruction for all of them (an AVX-512 register holds sixteen f32), and only the traversal,
//! the table lookups (triangles, materials, lights) and the BSDFs other than Lambertian run lane
//! by lane.
//!
//! Each lane computes exactly the operations the scalar integrator computes for its sample,
//! in the same order (`+ − × ÷ sqrt` are correctly rounded lane by lane, and nothing is
//! fused), so the image is the scalar integrator's bit for bit: the tests compare every lane
//! function with its scalar original, and whole renders with the scalar integrator's
//! (`tests/cli.rs`). The scalar integrator stays the reference: the GPU, the pixel replay and
//! every feature this one does not cover run it. What this one covers is
//! `integrator::covers`: every material kind (with textures, alpha masks and vertex normals or
//! without; the Lambertian BSDF in lanes, the others lane by lane through `material`),
//! emitting triangles and a constant environment, the radiance image.
//!
//! - `sampler`: the sampler's sets for sixteen samples (`rng::Sampler`, `sobol`).
//! - `warp`: the camera, warps, hit points, ray offsets and the MIS weight.
//! - `brute`: sixteen rays against every triangle of a small scene at once.
//! - `split`: sixteen rays against a few large triangles at once, and a BVH over the others.
//! - `integrator`: the path loop.
use core::simd::cmp::SimdPartialOrd;
use core::simd::{Mask, Select, Simd};

pub mod brute;
pub mod connection;
pub mod integrator;
pub mod sampler;
pub mod split;
pub mod warp;

/// Samples a step takes at once: an AVX-512 register's f32 lanes.
pub const LANES: usize = 16;

/// Sixteen f32.
pub type F = Simd<f32, LANES>;
/// Sixteen u32.
pub type U = Simd<u32, LANES>;
/// Sixteen booleans, one per lane.
pub type M = Mask<i32, LANES>;

/// The correctly rounded square root, lane by lane (`vsqrtps`), as `f32::sqrt` per lane.
#[inline(always)]
pub fn sqrt(x: F) -> F {
    // SAFETY: `F` is a SIMD vector of floats, as the intrinsic requires.
    unsafe { core::intrinsics::simd::simd_fsqrt(x) }
}

/// `a > b ? a : b` lane by lane: `f32::max` for the values here, which are never NaN.
#[inline(always)]
pub fn max(a: F, b: F) -> F {
    a.simd_gt(b).select(a, b)
}

/// The hits of sixteen rays: triangle (`NO_HIT` for none), distance and the unnormalised
/// barycentric weights, as rows.
pub struct Hits {
    pub triangle: U,
    pub t: F,
    pub u: F,
    pub v: F,
    pub w: F,
}

/// Sixteen 3-vectors, one per lane, as three rows.
#[derive(Clone, Copy, Debug)]
pub struct V3 {
    pub x: F,
    pub y: F,
    pub z: F,
}

impl V3 {
    pub const ZERO: V3 =
        V3 { x: F::from_array([0.0; LANES]), y: F::from_array([0.0; LANES]), z: F::from_array([0.0; LANES]) };

    #[inline(always)]
    pub fn new(x: F, y: F, z: F) -> Self {
        Self { x, y, z }
    }

    /// The same vector in every lane.
    #[inline(always)]
    pub fn splat(v: crate::glam::Vec3) -> Self {
        Self { x: F::splat(v.x), y: F::splat(v.y), z: F::splat(v.z) }
    }

    /// Lane `i`'s vector.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> crate::glam::Vec3 {
        crate::glam::Vec3::new(self.x[i], self.y[i], self.z[i])
    }

    /// From one vector per lane.
    #[inline(always)]
    pub fn from_lanes(v: &[crate::glam::Vec3; LANES]) -> Self {
        Self {
            x: F::from_array(core::array::from_fn(|i| v[i].x)),
            y: F::from_array(core::array::from_fn(|i| v[i].y)),
            z: F::from_array(core::array::from_fn(|i| v[i].z)),
        }
    }

    /// `m ? a : b` lane by lane.
    #[inline(always)]
    pub fn select(m: M, a: Self, b: Self) -> Self {
        Self { x: m.select(a.x, b.x), y: m.select(a.y, b.y), z: m.select(a.z, b.z) }
    }

    /// Each component times `s` (glam's `Vec3 * f32`).
    #[inline(always)]
    pub fn scale(self, s: F) -> Self {
        Self { x: self.x * s, y: self.y * s, z: self.z * s }
    }

    /// Each component divided by `s` (glam's `Vec3 / f32`).
    #[inline(always)]
    pub fn divide(self, s: F) -> Self {
        Self { x: self.x / s, y: self.y / s, z: self.z / s }
    }

    /// `vecmath::dot`.
    #[inline(always)]
    pub fn dot(self, o: Self) -> F {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// `vecmath::cross`.
    #[inline(always)]
    pub fn cross(self, b: Self) -> Self {
        Self { x: self.y * b.z - self.z * b.y, y: self.z * b.x - self.x * b.z, z: self.x * b.y - self.y * b.x }
    }

    /// `vecmath::normalize`: times the reciprocal of the length.
    #[inline(always)]
    pub fn normalize(self) -> Self {
        self.scale(F::splat(1.0) / sqrt(self.dot(self)))
    }

    /// Whether any component is above zero, lane by lane.
    #[inline(always)]
    pub fn any_positive(self) -> M {
        let z = F::splat(0.0);
        self.x.simd_gt(z) | self.y.simd_gt(z) | self.z.simd_gt(z)
    }
}

impl core::ops::Add for V3 {
    type Output = V3;
    #[inline(always)]
    fn add(self, o: V3) -> V3 {
        V3 { x: self.x + o.x, y: self.y + o.y, z: self.z + o.z }
    }
}

impl core::ops::Sub for V3 {
    type Output = V3;
    #[inline(always)]
    fn sub(self, o: V3) -> V3 {
        V3 { x: self.x - o.x, y: self.y - o.y, z: self.z - o.z }
    }
}

/// Component by component, as glam's `Vec3 * Vec3`.
impl core::ops::Mul for V3 {
    type Output = V3;
    #[inline(always)]
    fn mul(self, o: V3) -> V3 {
        V3 { x: self.x * o.x, y: self.y * o.y, z: self.z * o.z }
    }
}

impl core::ops::Neg for V3 {
    type Output = V3;
    #[inline(always)]
    fn neg(self) -> V3 {
        V3 { x: -self.x, y: -self.y, z: -self.z }
    }
}
