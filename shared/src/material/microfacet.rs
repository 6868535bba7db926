//! The GGX (Trowbridge–Reitz) microfacet distribution, isotropic, in a local frame whose z is
//! the macro-surface normal: the normal distribution D (Walter et al. 2007), Smith's separable
//! masking G1, and sampling of the normals visible from a direction (Heitz 2018, "Sampling the
//! GGX Distribution of Visible Normals", JCGT 7(4)), as Mitsuba 3's `MicrofacetDistribution`
//! with `sample_visible = true`.
use crate::glam::Vec3;
use crate::sampling::{concentric_disk, PI};
use crate::vecmath::{cross, dot, normalize};
#[allow(unused_imports)]
use spirv_std::num_traits::Float;

/// D(m) = α² / (π (α² m_z² + m_x² + m_y²)²) for a unit normal m (the usual
/// (m_z²(α² − 1) + 1)² with 1 − m_z² written as m_x² + m_y²: a shader compiler turns
/// 1 + x·(α² − 1) into a linear interpolation, which rounds differently from the CPU); 0 below
/// the surface.
#[inline]
pub fn ggx_d(alpha: f32, m: Vec3) -> f32 {
    if m.z <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let t = a2 * (m.z * m.z) + (m.x * m.x + m.y * m.y);
    a2 / (PI * t * t)
}

/// Smith's masking G1(w, m) = 2 w_z / (w_z + √(α²(w_x² + w_y²) + w_z²)) for a unit w (the
/// usual √(α² + (1 − α²) w_z²), written without the interpolation a shader compiler would
/// rewrite), 0 when w sees m's back or lies below the surface.
#[inline]
pub fn ggx_g1(alpha: f32, w: Vec3, m: Vec3) -> f32 {
    if (w.z <= 0.0) | (dot(w, m) <= 0.0) {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let root = (a2 * (w.x * w.x + w.y * w.y) + w.z * w.z).sqrt();
    2.0 * w.z / (w.z + root)
}

/// Smith's masking for a direction on either side of the surface (a refracted one below it):
/// `ggx_g1` of w mirrored to the upper side, 0 when w sees the side of m it is not on
/// ((w·m)·w_z ≤ 0, Mitsuba's `smith_g1` side test).
#[inline]
pub fn ggx_g1_two_sided(alpha: f32, w: Vec3, m: Vec3) -> f32 {
    if dot(w, m) * w.z <= 0.0 {
        return 0.0;
    }
    let z = w.z.abs();
    let a2 = alpha * alpha;
    let root = (a2 * (w.x * w.x + w.y * w.y) + z * z).sqrt();
    2.0 * z / (z + root)
}

/// A microfacet normal visible from `w` (w_z > 0), with density D_w(m) = G1(w, m)·(w·m)·D(m)/w_z.
/// The disk point comes from the concentric map, so both devices compute it with the same
/// polynomials (`trig`).
#[inline]
pub fn ggx_sample_visible(alpha: f32, w: Vec3, u1: f32, u2: f32) -> Vec3 {
    ggx_sample_visible_at(alpha, w, concentric_disk(u1, u2))
}

/// `ggx_sample_visible` from the point (p1, p2) of the unit disk that `concentric_disk` gave:
/// `material::sample` maps its uniforms onto the disk once for whichever material it samples.
#[inline]
pub fn ggx_sample_visible_at(alpha: f32, w: Vec3, (p1, p2): (f32, f32)) -> Vec3 {
    // The view direction in the hemisphere configuration (α stretched to 1).
    let v = normalize(Vec3::new(alpha * w.x, alpha * w.y, w.z));
    let len2 = v.x * v.x + v.y * v.y;
    let t1 = if len2 > 0.0 { Vec3::new(-v.y, v.x, 0.0) * (1.0 / len2.sqrt()) } else { Vec3::X };
    let t2 = cross(v, t1);
    // Warp the disk onto the visible half of the projected hemisphere, with s and 1 − s written
    // out: the SPIR-V optimiser folds 1 − 0.5·(1 + z) into 0.5 − 0.5·z, which rounds differently.
    let (s, one_minus_s) = (0.5 + 0.5 * v.z, 0.5 - 0.5 * v.z);
    let h = (1.0 - p1 * p1).max(0.0).sqrt();
    let p2 = one_minus_s * h + s * p2;
    let pz = (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
    let nh = t1 * p1 + t2 * p2 + v * pz;
    // Back to the ellipsoid configuration.
    normalize(Vec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(0.0)))
}

/// The solid-angle pdf of a reflected direction whose half vector m was drawn by
/// `ggx_sample_visible` from `w`: D_w(m) / (4 w·m) = G1(w, m)·D(m) / (4 w_z).
#[inline]
pub fn ggx_visible_pdf(alpha: f32, w: Vec3, m: Vec3) -> f32 {
    if w.z <= 0.0 {
        return 0.0;
    }
    ggx_g1(alpha, w, m) * ggx_d(alpha, m) / (4.0 * w.z)
}
