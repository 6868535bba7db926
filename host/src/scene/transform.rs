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
//!
//! Placement runs in f64 on f64 vertices (`WorldTriangle`): a mesh placed at survey coordinates
//! is rounded to f32 once, in the scene's local frame (`local_frame::place`).
use crate::scene::WorldTriangle;
use shared::glam::{DMat3, DMat4, DQuat, DVec3, EulerRot};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    pub scale: DVec3,
    /// Degrees about x, then y, then z (world axes).
    pub rotate_deg: DVec3,
    pub translate: DVec3,
}

impl Default for Placement {
    fn default() -> Self {
        Self { scale: DVec3::ONE, rotate_deg: DVec3::ZERO, translate: DVec3::ZERO }
    }
}

impl Placement {
    pub fn is_identity(&self) -> bool {
        *self == Self::default()
    }

    /// The rotation Rz·Ry·Rx.
    pub fn rotation(&self) -> DQuat {
        let r = self.rotate_deg;
        // glam's EulerRot::ZYX builds Rz·Ry·Rx from (z, y, x) angles.
        DQuat::from_euler(EulerRot::ZYX, r.z.to_radians(), r.y.to_radians(), r.x.to_radians())
    }

    /// M = T · R · S.
    pub fn matrix(&self) -> DMat4 {
        DMat4::from_scale_rotation_translation(self.scale, self.rotation(), self.translate)
    }

    /// Whether the transform mirrors (and so reverses the winding).
    pub fn mirrors(&self) -> bool {
        DMat3::from_diagonal(self.scale).determinant() < 0.0
    }

    /// Places the triangles, keeping each face's front side as described in the module docs.
    pub fn apply(&self, triangles: &mut [WorldTriangle]) {
        if self.is_identity() {
            return;
        }
        let m = self.matrix();
        let swap = self.mirrors();
        for t in triangles {
            let [v0, v1, v2] = t.map(|v| m.transform_point3(v));
            *t = if swap { [v0, v2, v1] } else { [v0, v1, v2] };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_is_scale_rotate_translate() {
        let p = Placement {
            scale: DVec3::new(2.0, 1.0, 1.0),
            rotate_deg: DVec3::new(0.0, 0.0, 90.0),
            translate: DVec3::new(0.0, 0.0, 5.0),
        };
        // (1,0,0) → scale (2,0,0) → 90° about z (0,2,0) → translate (0,2,5).
        let q = p.matrix().transform_point3(DVec3::X);
        assert!((q - DVec3::new(0.0, 2.0, 5.0)).length() < 1e-12, "{q:?}");
    }

    #[test]
    fn x_rotation_comes_before_y() {
        let p = Placement { rotate_deg: DVec3::new(90.0, 90.0, 0.0), ..Default::default() };
        // (0,1,0) → 90° about x: (0,0,1) → 90° about y: (1,0,0).
        let q = p.matrix().transform_point3(DVec3::Y);
        assert!((q - DVec3::X).length() < 1e-12, "{q:?}");
    }

    #[test]
    fn mirroring_swaps_winding_so_the_front_follows_the_mirror() {
        let t = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let normal = |t: &WorldTriangle| (t[1] - t[0]).cross(t[2] - t[0]);
        assert!(normal(&t).z > 0.0);
        let mut tris = [t];
        Placement { scale: DVec3::new(1.0, 1.0, -1.0), ..Default::default() }.apply(&mut tris);
        // The face looked toward +z; its mirror image across z = 0 looks toward −z.
        assert!(normal(&tris[0]).z < 0.0, "{:?}", normal(&tris[0]));
        let mut tris = [t];
        Placement { scale: DVec3::new(-1.0, 1.0, 1.0), ..Default::default() }.apply(&mut tris);
        // Mirroring across x = 0 leaves a +z-facing face facing +z.
        assert!(normal(&tris[0]).z > 0.0);
    }
}
