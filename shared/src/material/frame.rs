//! An orthonormal shading frame about a unit normal (z), for BSDFs written in local coordinates.
use crate::glam::Vec3;
use crate::sampling::orthonormal_basis;
use crate::vecmath::dot;

#[derive(Clone, Copy)]
pub struct Frame {
    pub t: Vec3,
    pub b: Vec3,
    pub n: Vec3,
}

impl Frame {
    #[inline]
    pub fn new(n: Vec3) -> Self {
        let (t, b) = orthonormal_basis(n);
        Self { t, b, n }
    }

    #[inline]
    pub fn to_local(&self, w: Vec3) -> Vec3 {
        Vec3::new(dot(w, self.t), dot(w, self.b), dot(w, self.n))
    }

    #[inline]
    pub fn to_world(&self, w: Vec3) -> Vec3 {
        self.t * w.x + self.b * w.y + self.n * w.z
    }
}
