//! What the BVH builder sorts: axis-aligned boxes that grow, and references, each a triangle
//! id with the box of the part of the triangle that a node holds (the whole triangle, or a part
//! that spatial splits cut off).
use shared::glam::Vec3;

/// A box that grows: empty until something is added.
#[derive(Clone, Copy, Debug)]
pub struct Aabb {
    pub lo: Vec3,
    pub hi: Vec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb { lo: Vec3::splat(f32::INFINITY), hi: Vec3::splat(f32::NEG_INFINITY) };

    #[inline]
    pub fn grow(&mut self, lo: Vec3, hi: Vec3) {
        self.lo = self.lo.min(lo);
        self.hi = self.hi.max(hi);
    }

    /// Half the surface area; 0 for an empty box.
    #[inline]
    pub fn half_area(&self) -> f32 {
        let d = (self.hi - self.lo).max(Vec3::ZERO);
        d.x * d.y + d.y * d.z + d.z * d.x
    }

    /// The common part; empty (`is_empty`) where the boxes are apart.
    #[inline]
    pub fn intersect(&self, o: &Aabb) -> Aabb {
        Aabb { lo: self.lo.max(o.lo), hi: self.hi.min(o.hi) }
    }

    /// True when no point is inside (a point or a flat box is not empty).
    #[inline]
    pub fn is_empty(&self) -> bool {
        !(self.lo.x <= self.hi.x && self.lo.y <= self.hi.y && self.lo.z <= self.hi.z)
    }

    #[inline]
    pub fn centre(&self) -> Vec3 {
        (self.lo + self.hi) * 0.5
    }
}

/// A triangle id and the box of the part of it that a node holds.
#[derive(Clone, Copy, Debug)]
pub struct Ref {
    pub id: u32,
    pub b: Aabb,
}
