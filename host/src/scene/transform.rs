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
use crate::scene::{WorldAttributes, WorldTriangle};
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

    /// Places the vertex attributes of the triangles `apply` places: normals by the inverse
    /// transpose of the linear part, (R·S)⁻ᵀ = R·S⁻¹ (pbrt-v4 §3.10.3), renormalised in f64; the
    /// vertices' attributes swap with the vertices of a mirrored triangle.
    pub fn apply_attributes(&self, attributes: &mut [WorldAttributes]) {
        if self.is_identity() {
            return;
        }
        let (rotation, inverse_scale) = (self.rotation(), self.scale.recip());
        let swap = self.mirrors();
        for a in attributes {
            let n = a.normals.map(|n| if n == DVec3::ZERO { n } else { (rotation * (n * inverse_scale)).normalize() });
            let uv = a.uv;
            (a.normals, a.uv) = if swap { ([n[0], n[2], n[1]], [uv[0], uv[2], uv[1]]) } else { (n, uv) };
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

    #[test]
    fn normals_follow_the_surface_under_any_placement() {
        // A slanted face with its unit normal at each vertex; after a non-uniform, mirroring
        // placement the placed normal must be perpendicular to the placed face and unit.
        let t = [DVec3::ZERO, DVec3::new(1.0, 0.0, 1.0), DVec3::Y];
        let n = (t[1] - t[0]).cross(t[2] - t[0]).normalize();
        let p = Placement {
            scale: DVec3::new(3.0, -0.5, 1.0),
            rotate_deg: DVec3::new(10.0, 20.0, 30.0),
            translate: DVec3::new(1.0, 2.0, 3.0),
        };
        let mut tris = [t];
        let mut attributes = [WorldAttributes { normals: [n; 3], uv: [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]] }];
        p.apply(&mut tris);
        p.apply_attributes(&mut attributes);
        let placed = (tris[0][1] - tris[0][0]).cross(tris[0][2] - tris[0][0]).normalize();
        for m in attributes[0].normals {
            assert!((m.length() - 1.0).abs() < 1e-12);
            // The same side as the placed face's front (the winding swap keeps the front).
            assert!((m - placed).length() < 1e-12, "{m} vs {placed}");
        }
        // The texture coordinates moved with their vertices.
        assert_eq!(attributes[0].uv, [[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]]);
    }
}
