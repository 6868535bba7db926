//! Vector helpers written out in scalar arithmetic.
//!
//! glam may lower `dot`, `length` and `normalize` to SPIR-V's `OpDot` / GLSL `Normalize`, whose
//! rounding is the driver's choice. Spelling them out keeps CPU and GPU on the same operations.
use crate::glam::{Vec3, Vec4};
// `sqrt` is not in `core`: num-traits' `Float` supplies it (libm on the host, an intrinsic on the GPU).
#[allow(unused_imports)]
use spirv_std::num_traits::Float;

#[inline]
pub fn dot(a: Vec3, b: Vec3) -> f32 {
    a.x * b.x + a.y * b.y + a.z * b.z
}

#[inline]
pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x)
}

#[inline]
pub fn length_squared(a: Vec3) -> f32 {
    dot(a, a)
}

#[inline]
pub fn length(a: Vec3) -> f32 {
    dot(a, a).sqrt()
}

#[inline]
pub fn normalize(a: Vec3) -> Vec3 {
    a * (1.0 / length(a))
}

#[inline]
pub fn max_component(a: Vec3) -> f32 {
    a.x.max(a.y).max(a.z)
}

/// Component `i` (0, 1, 2) of `v`; a `match` lowers to selects on the GPU.
#[inline]
pub fn axis(v: Vec3, i: u32) -> f32 {
    if i == 0 {
        v.x
    } else if i == 1 {
        v.y
    } else {
        v.z
    }
}

#[inline]
pub fn xyz(v: Vec4) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

#[inline]
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}
