//! What a hit needs beyond its triangle: vertex attributes interpolated at the hit (texture
//! coordinates, shading normals), the material with its textures looked up (`resolve`), and
//! alpha cut-outs (`cut_out`).
//!
//! Materials: a texture replaces the constant its slot covers, as Mitsuba's `bitmap` replaces a
//! reflectance: `albedo.xyz` (MTL `map_Kd`), `emission.xyz` (`map_Ke`), the GGX α in `params.x`
//! from a perceptual roughness r as α = r² (`map_Pr`; the glTF/Disney convention), the metallic
//! weight in `params.z` (`map_Pm`). The BSDFs only ever see the resolved, plain `Material`.
//!
//! Shading normals (pbrt-v4 §10.1.1 and §9.1; Veach 1996 §5.3 on the asymmetry they cause):
//! the vertex normals interpolated with the hit's barycentric weights and normalised, turned to
//! the side of the flat (geometric) normal and then, with it, toward the arriving ray. Where the
//! outgoing direction `wo` lies below the shading normal's horizon, the flat normal shades
//! instead (the interpolated one would make the surface face away from the viewer). A sampled or
//! light direction `wi` that lies on different sides of the flat and the shading normal carries
//! nothing (`consistent`): where the two disagree, light would otherwise leak through the surface
//! (pbrt-v3 §9.1 `BSDF::f` decides reflection against transmission by the geometric normal for
//! the same reason; this guard is the stricter form that also ends such sampled paths).
//! A material's normal map (`TEXTURE_NORMAL`, glTF's `normalTexture`) bends the interpolated
//! normal (or the flat one) first, in the tangent frame of the triangle's texture coordinates
//! (`normal_mapped`); the guards then apply to the bent normal alike.
//!
//! Alpha: a hit whose alpha mask reads below `ALPHA_CUTOFF` at its texture coordinates does not
//! count for any ray (camera, bounce, shadow): the traversals skip it inside their leaf test and
//! go on to the next triangle (`kdtree::test_leaf`), so the closest hit that counts is found in
//! one traversal on either device.
use crate::features::{Variant, FEATURE_TEXTURES, FEATURE_VERTEX_NORMALS};
use crate::glam::{Vec2, Vec3};
use crate::kdtree::Hit;
use crate::layout::{
    Material, ALPHA_BLEND, ALPHA_CUTOFF, NO_TEXTURE, TEXTURE_ALBEDO, TEXTURE_ALPHA, TEXTURE_CLEARCOAT,
    TEXTURE_EMISSION, TEXTURE_METALLIC, TEXTURE_NORMAL, TEXTURE_ROUGHNESS,
};
use crate::rng::{pcg4d, u32_to_unit_f32};
use crate::scene::SceneView;
use crate::texture::sample;
use crate::vecmath::{cross, dot, length_squared, normalize, xyz};

/// Barycentric weights (b0, b1, b2) of v0, v1, v2 from a hit's unnormalised weights: the same
/// operations as `triangle::hit_point`, so the point and its attributes agree.
#[inline(always)]
pub fn weights(u: f32, v: f32, w: f32) -> (f32, f32, f32) {
    let inv = 1.0 / (u + v + w);
    (u * inv, v * inv, w * inv)
}

/// A hit's barycentric weights.
#[inline(always)]
pub fn hit_weights(hit: &Hit) -> (f32, f32, f32) {
    weights(hit.u, hit.v, hit.w)
}

/// Texture coordinates of triangle `tri` at weights `b`; (0, 0) where it has none.
#[inline(always)]
pub fn uv_at(scene: &SceneView, tri: u32, b: (f32, f32, f32)) -> Vec2 {
    if (tri as usize) < scene.attributes.len() {
        let a = &scene.attributes[tri as usize];
        let u = a.n0.w * b.0 + a.n1.w * b.1 + a.n2.w * b.2;
        let v = a.uv_v.x * b.0 + a.uv_v.y * b.1 + a.uv_v.z * b.2;
        Vec2::new(u, v)
    } else {
        Vec2::ZERO
    }
}

/// The vertex normals of `tri` interpolated at weights `b`, not normalised; zero where the
/// triangle has none.
#[inline(always)]
pub fn interpolated_normal(scene: &SceneView, tri: u32, b: (f32, f32, f32)) -> Vec3 {
    if (tri as usize) < scene.attributes.len() {
        let a = &scene.attributes[tri as usize];
        let (n0, n1, n2) = (a.n0, a.n1, a.n2);
        Vec3::new(
            n0.x * b.0 + n1.x * b.1 + n2.x * b.2,
            n0.y * b.0 + n1.y * b.1 + n2.y * b.2,
            n0.z * b.0 + n1.z * b.1 + n2.z * b.2,
        )
    } else {
        Vec3::ZERO
    }
}

/// The shading normal at a hit on `tri` (weights `b`): `flat` (the unit geometric normal turned
/// toward the arriving ray) where the triangle has no vertex normals, where they cancel, or where
/// `wo` (toward the viewer) lies below the interpolated normal; otherwise the interpolated normal
/// on `flat`'s side (module docs).
#[inline(always)]
pub fn shading_normal(scene: &SceneView, v: Variant, tri: u32, b: (f32, f32, f32), flat: Vec3, wo: Vec3) -> Vec3 {
    let mut ns = flat;
    if v.has(FEATURE_VERTEX_NORMALS) & !scene.attributes.is_empty() {
        let mut n = interpolated_normal(scene, tri, b);
        // A normal map: only in a scene with textures (its material is looked up only then).
        if v.has(FEATURE_TEXTURES) & !scene.textures.is_empty() & ((tri as usize) < scene.attributes.len()) {
            let m = &scene.materials[scene.info[tri as usize].material as usize];
            let map = m.textures[TEXTURE_NORMAL];
            if map != NO_TEXTURE {
                let base = if length_squared(n) > 0.0 { normalize(n) } else { flat };
                n = normal_mapped(scene, tri, b, base, map, m.eta.w);
            }
        }
        if length_squared(n) > 0.0 {
            let n = normalize(n);
            let n = if dot(n, flat) < 0.0 { -n } else { n };
            if dot(n, wo) > 0.0 {
                ns = n;
            }
        }
    }
    ns
}

/// The unit normal `n` bent by normal map `map` (slot value) of scale `scale` at weights `b` on
/// triangle `tri`, in the tangent frame of the triangle's texture coordinates: the tangent is
/// ∂p/∂u made perpendicular to `n`, the bitangent n × t on the side of ∂p/∂v (MikkTSpace's
/// per-triangle frame, without its vertex averaging). `n` itself where the texture coordinates
/// are degenerate.
#[inline(always)]
pub fn normal_mapped(scene: &SceneView, tri: u32, b: (f32, f32, f32), n: Vec3, map: u32, scale: f32) -> Vec3 {
    let t = &scene.triangles[tri as usize];
    let a = &scene.attributes[tri as usize];
    let (e1, e2) = (xyz(t.v1) - xyz(t.v0), xyz(t.v2) - xyz(t.v0));
    let (du1, dv1) = (a.n1.w - a.n0.w, a.uv_v.y - a.uv_v.x);
    let (du2, dv2) = (a.n2.w - a.n0.w, a.uv_v.z - a.uv_v.x);
    let det = du1 * dv2 - du2 * dv1;
    let mut out = n;
    if det != 0.0 {
        let tangent = e1 * dv2 - e2 * dv1;
        let bitangent = e2 * du1 - e1 * du2;
        // The sign of det orients both; only the bitangent's side relative to n × t matters.
        let tangent = if det < 0.0 { -tangent } else { tangent };
        let bitangent = if det < 0.0 { -bitangent } else { bitangent };
        let tg = tangent - n * dot(n, tangent);
        if length_squared(tg) > 0.0 {
            let tg = normalize(tg);
            let side = cross(n, tg);
            let bt = if dot(side, bitangent) < 0.0 { -side } else { side };
            let c = sample(scene.textures, map - 1, uv_at(scene, tri, b));
            let x = (c.x * 2.0 - 1.0) * scale;
            let y = (c.y * 2.0 - 1.0) * scale;
            let z = c.z * 2.0 - 1.0;
            let bent = tg * x + bt * y + n * z;
            if length_squared(bent) > 0.0 {
                out = normalize(bent);
            }
        }
    }
    out
}

/// Whether direction `wi` lies on the same side of the flat normal as of the shading normal `ns`
/// (always, when the two are the same): a direction for which they disagree carries no light
/// (module docs).
#[inline(always)]
pub fn consistent(v: Variant, flat: Vec3, ns: Vec3, wi: Vec3) -> bool {
    !v.has(FEATURE_VERTEX_NORMALS) | ((dot(flat, wi) > 0.0) == (dot(ns, wi) > 0.0))
}

/// Whether `resolve` changes `m`: the variant and the scene have textures and `m` has a map
/// other than its alpha mask.
#[inline(always)]
pub fn looks_up_textures(scene: &SceneView, v: Variant, m: &Material) -> bool {
    let t = m.textures;
    v.has(FEATURE_TEXTURES)
        & !scene.textures.is_empty()
        & ((t[TEXTURE_ALBEDO] != NO_TEXTURE)
            | (t[TEXTURE_EMISSION] != NO_TEXTURE)
            | (t[TEXTURE_ROUGHNESS] != NO_TEXTURE)
            | (t[TEXTURE_METALLIC] != NO_TEXTURE)
            | (t[TEXTURE_CLEARCOAT] != NO_TEXTURE))
}

/// `m` with its textures looked up at weights `b` on triangle `tri` (module docs); `m` itself
/// when it has none or the variant has no textures.
#[inline(always)]
pub fn resolve(scene: &SceneView, v: Variant, m: &Material, tri: u32, b: (f32, f32, f32)) -> Material {
    let mut r = *m;
    // A scene without textures (an empty buffer) skips the slots: one compare per hit on the
    // CPU, whose variants all have the texture bit.
    if looks_up_textures(scene, v, m) {
        let uv = uv_at(scene, tri, b);
        // The slots in a loop, one `sample` for all five: a shader inlines it once here instead
        // of five times (README, "Shader size").
        let mut k = 0;
        while k < RESOLVED.len() {
            let map = m.textures[RESOLVED[k]];
            if map != NO_TEXTURE {
                let c = sample(scene.textures, map - 1, uv);
                match RESOLVED[k] {
                    TEXTURE_ALBEDO => {
                        r.albedo.x = c.x;
                        r.albedo.y = c.y;
                        r.albedo.z = c.z;
                    }
                    TEXTURE_EMISSION => {
                        r.emission.x = c.x;
                        r.emission.y = c.y;
                        r.emission.z = c.z;
                    }
                    TEXTURE_ROUGHNESS => r.params.x = c.x * c.x,
                    TEXTURE_METALLIC => r.params.z = c.x,
                    _ => r.eta.x = c.x,
                }
            }
            k += 1;
        }
    }
    r
}

/// The slots `resolve` looks up, in its order; the last is `TEXTURE_CLEARCOAT`.
const RESOLVED: [usize; 5] = [TEXTURE_ALBEDO, TEXTURE_EMISSION, TEXTURE_ROUGHNESS, TEXTURE_METALLIC, TEXTURE_CLEARCOAT];

/// The emitted radiance of `m` on triangle `tri` at weights `b` (its emission texture there,
/// or its constant): what light sampling picks up from a point it chose on a lamp.
#[inline(always)]
pub fn emission_at(scene: &SceneView, v: Variant, m: &Material, tri: u32, b: (f32, f32, f32)) -> Vec3 {
    let mut e = xyz(m.emission);
    if v.has(FEATURE_TEXTURES) & !scene.textures.is_empty() & (m.textures[TEXTURE_EMISSION] != NO_TEXTURE) {
        let c = sample(scene.textures, m.textures[TEXTURE_EMISSION] - 1, uv_at(scene, tri, b));
        e = Vec3::new(c.x, c.y, c.z);
    }
    e
}

/// The material of the triangle hit, resolved at the hit (`resolve`).
#[inline(always)]
pub fn material_at(scene: &SceneView, v: Variant, hit: &Hit) -> Material {
    let m = &scene.materials[scene.info[hit.triangle as usize].material as usize];
    resolve(scene, v, m, hit.triangle, hit_weights(hit))
}

/// Whether a hit on triangle `tri` with unnormalised weights (u, v, w) is cut out by its
/// material's alpha mask. Only tested when `scene.alpha_masks` is set (the variant has alpha
/// masks). Stochastic transparency (`ALPHA_BLEND`) compares alpha with a uniform hashed from
/// the triangle and the hit's weights: the same bits on every device, independent between
/// rays, and the same answer when the traversal tests the same hit again.
#[inline(always)]
pub fn cut_out(scene: &SceneView, tri: u32, u: f32, v: f32, w: f32) -> bool {
    let mut out = false;
    if scene.alpha_masks {
        let m = &scene.materials[scene.info[tri as usize].material as usize];
        let mask = m.textures[TEXTURE_ALPHA];
        if mask != NO_TEXTURE {
            let uv = uv_at(scene, tri, weights(u, v, w));
            let alpha = sample(scene.textures, mask - 1, uv).x;
            let threshold = if m.alpha_mode == ALPHA_BLEND {
                u32_to_unit_f32(pcg4d(tri, u.to_bits(), v.to_bits(), w.to_bits())[0])
            } else {
                ALPHA_CUTOFF
            };
            out = alpha < threshold;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::FEATURES_ALL;
    use crate::glam::Vec4;
    use crate::layout::{RenderParams, TriangleAttributes};

    fn with_normals(n: Vec3, test: impl Fn(&SceneView)) {
        let a = TriangleAttributes { n0: n.extend(0.0), n1: n.extend(0.0), n2: n.extend(0.0), uv_v: Vec4::ZERO };
        let p = RenderParams::default();
        let attributes = [a];
        test(&SceneView::new(&p, &[], &[], &[], &[], &[], &[], &[], &attributes, &[], &[]));
    }

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).abs().max_element() < 1e-6
    }

    const ALL: Variant = Variant { features: FEATURES_ALL, max_bounces: 1, rr_start: 1 };
    const THIRD: (f32, f32, f32) = (0.25, 0.25, 0.5);

    #[test]
    fn the_shading_normal_faces_the_flat_side_and_the_viewer() {
        let flat = Vec3::Z;
        let tilted = Vec3::new(0.6, 0.0, 0.8);
        with_normals(tilted, |s| {
            assert!(close(shading_normal(s, ALL, 0, THIRD, flat, Vec3::Z), tilted));
            // Without the feature bit, or beyond the attributes, the flat normal.
            let none = Variant { features: 0, ..ALL };
            assert_eq!(shading_normal(s, none, 0, THIRD, flat, Vec3::Z), flat);
            assert_eq!(shading_normal(s, ALL, 1, THIRD, flat, Vec3::Z), flat);
            // A viewer below the interpolated normal's horizon sees the flat normal.
            let grazing = normalize(Vec3::new(-0.9, 0.0, 0.1));
            assert_eq!(shading_normal(s, ALL, 0, THIRD, flat, grazing), flat);
        });
        // Vertex normals on the other side are turned to the flat normal's side.
        with_normals(-tilted, |s| assert!(close(shading_normal(s, ALL, 0, THIRD, flat, Vec3::Z), tilted)));
        // Normals that cancel leave the flat one.
        with_normals(Vec3::ZERO, |s| assert_eq!(shading_normal(s, ALL, 0, THIRD, flat, Vec3::Z), flat));
    }

    #[test]
    fn directions_between_the_two_horizons_carry_nothing() {
        let (flat, ns) = (Vec3::Z, Vec3::new(0.6, 0.0, 0.8));
        // Above both, below both: consistent. Below the flat, above the shading normal: not.
        assert!(consistent(ALL, flat, ns, normalize(Vec3::new(0.1, 0.0, 1.0))));
        assert!(consistent(ALL, flat, ns, normalize(Vec3::new(0.1, 0.0, -1.0))));
        let between = normalize(Vec3::new(1.0, 0.0, -0.1));
        assert!(!consistent(ALL, flat, ns, between));
        assert!(consistent(Variant { features: 0, ..ALL }, flat, ns, between));
    }
}
