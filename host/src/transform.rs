//! Mesh placement in a scene file: scale, then rotate, then translate.
//!
//! Rotation is given as three angles in degrees about the fixed world axes x, then y, then z
//! (extrinsic X→Y→Z, i.e. the matrix Rz·Ry·Rx, the convention of Mitsuba's `rotate` tags applied
//! in that order and of glam's `EulerRot::XYZ` read as extrinsic). The whole transform is
//! M = T · Rz · Ry · Rx · S, applied to points.
//!
//! A transform with a negative determinant (an odd number of negative scale factors) mirrors the
//! mesh, and mirroring reverses the order in which a face's vertices wind. Emission is one-sided
//! from the counter-clockwise side, so vertices 1 and 2 of every triangle are swapped under such a
//! transform: the front side of each face stays the mirror image of its original front side, and
//! a mirrored light still shines into the mirrored room (pbrt-v4 `Transform::SwapsHandedness`
//! handles the same case by flipping the normal).
use shared::glam::{EulerRot, Mat3, Mat4, Quat, Vec3, Vec4};
use shared::layout::Triangle;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    pub scale: Vec3,
    /// Degrees about x, then y, then z (world axes).
    pub rotate_deg: Vec3,
    pub translate: Vec3,
}

impl Default for Placement {
    fn default() -> Self {
        Self { scale: Vec3::ONE, rotate_deg: Vec3::ZERO, translate: Vec3::ZERO }
    }
}

impl Placement {
    pub fn is_identity(&self) -> bool {
        *self == Self::default()
    }

    /// The rotation Rz·Ry·Rx.
    pub fn rotation(&self) -> Quat {
        let r = self.rotate_deg;
        // glam's EulerRot::ZYX builds Rz·Ry·Rx from (z, y, x) angles.
        Quat::from_euler(EulerRot::ZYX, r.z.to_radians(), r.y.to_radians(), r.x.to_radians())
    }

    /// M = T · R · S.
    pub fn matrix(&self) -> Mat4 {
        Mat4::from_scale_rotation_translation(self.scale, self.rotation(), self.translate)
    }

    /// Whether the transform mirrors (and so reverses the winding).
    pub fn mirrors(&self) -> bool {
        Mat3::from_diagonal(self.scale).determinant() < 0.0
    }

    /// Places the triangles, keeping each face's front side as described in the module docs.
    pub fn apply(&self, triangles: &mut [Triangle]) {
        if self.is_identity() {
            return;
        }
        let m = self.matrix();
        let swap = self.mirrors();
        let point = |v: Vec4| m.transform_point3(v.truncate()).extend(0.0);
        for t in triangles {
            let (v0, v1, v2) = (point(t.v0), point(t.v1), point(t.v2));
            *t = if swap { Triangle { v0, v1: v2, v2: v1 } } else { Triangle { v0, v1, v2 } };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_is_scale_rotate_translate() {
        let p = Placement {
            scale: Vec3::new(2.0, 1.0, 1.0),
            rotate_deg: Vec3::new(0.0, 0.0, 90.0),
            translate: Vec3::new(0.0, 0.0, 5.0),
        };
        // (1,0,0) → scale (2,0,0) → 90° about z (0,2,0) → translate (0,2,5).
        let q = p.matrix().transform_point3(Vec3::X);
        assert!((q - Vec3::new(0.0, 2.0, 5.0)).length() < 1e-5, "{q:?}");
    }

    #[test]
    fn x_rotation_comes_before_y() {
        let p = Placement { rotate_deg: Vec3::new(90.0, 90.0, 0.0), ..Default::default() };
        // (0,1,0) → 90° about x: (0,0,1) → 90° about y: (1,0,0).
        let q = p.matrix().transform_point3(Vec3::Y);
        assert!((q - Vec3::X).length() < 1e-5, "{q:?}");
    }

    #[test]
    fn mirroring_swaps_winding_so_the_front_follows_the_mirror() {
        let t = Triangle {
            v0: Vec4::new(0.0, 0.0, 0.0, 0.0),
            v1: Vec4::new(1.0, 0.0, 0.0, 0.0),
            v2: Vec4::new(0.0, 1.0, 0.0, 0.0),
        };
        let normal = |t: &Triangle| (t.v1 - t.v0).truncate().cross((t.v2 - t.v0).truncate());
        assert!(normal(&t).z > 0.0);
        let mut tris = [t];
        Placement { scale: Vec3::new(1.0, 1.0, -1.0), ..Default::default() }.apply(&mut tris);
        // The face looked toward +z; its mirror image across z = 0 looks toward −z.
        assert!(normal(&tris[0]).z < 0.0, "{:?}", normal(&tris[0]));
        let mut tris = [t];
        Placement { scale: Vec3::new(-1.0, 1.0, 1.0), ..Default::default() }.apply(&mut tris);
        // Mirroring across x = 0 leaves a +z-facing face facing +z.
        assert!(normal(&tris[0]).z > 0.0);
    }
}
