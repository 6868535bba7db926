//! What a scene uses, as bits of one `u32`, and the variant of the integrator compiled for it.
//!
//! A rust-gpu specialisation constant is a `u32` and a CPU variant a const generic: either way
//! the integrator reads its feature set through `Variant::has`, and a variant whose bit is off
//! leaves that work out (the compiler removes the branch). The host finds the set when it loads a
//! scene (`host::render::features`). Each bit gates work that the generic code (every bit set)
//! would do to no effect on a scene without the feature, so both give the same image bit for bit:
//! a new feature is one bit here and one `has` test around its code.
use crate::layout::RenderParams;

/// At least one emitting triangle: next-event estimation and MIS have something to sample.
pub const FEATURE_EMITTERS: u32 = 1 << 0;
/// More than one entry in the light table (emitting triangles, the environment map, punctual
/// lights): picking a light needs the table's distribution.
pub const FEATURE_MANY_EMITTERS: u32 = 1 << 1;
/// Rays that leave the scene bring radiance (a non-black environment).
pub const FEATURE_ENVIRONMENT: u32 = 1 << 2;
/// Lambertian diffuse materials are present (one bit per material kind from here on).
pub const FEATURE_DIFFUSE: u32 = 1 << 3;
/// Light can reach the camera by reflection: there is a source (an emitter or the environment)
/// and a material that reflects. Without it a path ends at its first hit, after its emission.
pub const FEATURE_INDIRECT: u32 = 1 << 4;
/// Conductors (`material::conductor`) are present.
pub const FEATURE_CONDUCTOR: u32 = 1 << 5;
/// Dielectrics (`material::dielectric`) are present.
pub const FEATURE_DIELECTRIC: u32 = 1 << 6;
/// Plastics (`material::plastic`) are present.
pub const FEATURE_PLASTIC: u32 = 1 << 7;
/// glTF metallic-roughness materials (`material::principled`) are present.
pub const FEATURE_PRINCIPLED: u32 = 1 << 8;
/// Some material has a texture map (`surface::resolve` fetches texels at each hit).
pub const FEATURE_TEXTURES: u32 = 1 << 9;
/// Some material has an alpha mask: hits are tested against it (`surface::cut_out`) in every
/// traversal.
pub const FEATURE_ALPHA_MASKS: u32 = 1 << 10;
/// Some triangle has vertex normals: shading interpolates them (`surface::shading_normal`).
pub const FEATURE_VERTEX_NORMALS: u32 = 1 << 11;
/// An environment map (`environment`): looked up by rays that leave the scene and sampled by
/// next-event estimation from the light table.
pub const FEATURE_ENVIRONMENT_MAP: u32 = 1 << 12;
/// Punctual lights (`punctual`: point, spot, directional) in the light table.
pub const FEATURE_PUNCTUAL: u32 = 1 << 13;
/// Light subpaths connect to the eye vertices (`integrator::connect`): a render setting, on only
/// where `connection_applies` to the scene's other bits. Unlike the bits above it changes the
/// estimator, so the generic code reads it from `RenderParams::connect` too.
pub const FEATURE_CONNECT: u32 = 1 << 14;
/// Every feature: the generic code, which serves any scene.
pub const FEATURES_ALL: u32 = (1 << 15) - 1;
/// The material-kind bits: when exactly one is set, material dispatch is skipped.
pub const FEATURE_MATERIALS: u32 =
    FEATURE_DIFFUSE | FEATURE_CONDUCTOR | FEATURE_DIELECTRIC | FEATURE_PLASTIC | FEATURE_PRINCIPLED;

/// Whether the connection strategy (`FEATURE_CONNECT`) serves a scene of feature bits `bits`:
/// emitting triangles and indirect light, Lambertian surfaces alone with flat normals and
/// without textures or alpha masks, and no environment map or punctual lights (its light
/// subpaths start on emitting triangles, and its vertices' BSDF is the albedo over pi).
pub const fn connection_applies(bits: u32) -> bool {
    let needs = FEATURE_EMITTERS | FEATURE_INDIRECT | FEATURE_DIFFUSE;
    let excludes = (FEATURE_MATERIALS & !FEATURE_DIFFUSE)
        | FEATURE_TEXTURES
        | FEATURE_ALPHA_MASKS
        | FEATURE_VERTEX_NORMALS
        | FEATURE_ENVIRONMENT_MAP
        | FEATURE_PUNCTUAL;
    (bits & needs == needs) & (bits & excludes == 0)
}

/// A bounce limit or roulette start given by specialisation constant: this value (the kernel's
/// default) means "read it from `RenderParams`".
pub const FROM_PARAMS: u32 = u32::MAX;

/// The specialisation constants' ids in the kernel (`#[spirv(spec_constant(id = N))]`), which
/// the host sets through wgpu's pipeline overrides (keys: the ids as decimal strings).
pub mod spec_id {
    /// The feature set (default `FEATURES_ALL`).
    pub const FEATURES: u32 = 0;
    /// The bounce limit (default `FROM_PARAMS`).
    pub const MAX_BOUNCES: u32 = 1;
    /// The bounce from which Russian roulette may end a path (default `FROM_PARAMS`).
    pub const RR_START: u32 = 2;
}

/// What one variant of the integrator is built for: the feature set, and the bounce limit and
/// roulette start (constants in a specialised GPU pipeline, read from the parameters elsewhere).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Variant {
    pub features: u32,
    pub max_bounces: u32,
    pub rr_start: u32,
}

impl Variant {
    /// The kernel's defaults: the generic code, limits from the parameters.
    pub const GENERIC_SPEC: Variant =
        Variant { features: FEATURES_ALL, max_bounces: FROM_PARAMS, rr_start: FROM_PARAMS };

    /// Feature set `features`, limits from the parameters (the CPU's const-generic variants).
    #[inline(always)]
    pub fn new(features: u32, p: &RenderParams) -> Self {
        Self { features, max_bounces: p.max_bounces, rr_start: p.rr_start }
    }

    /// From the kernel's specialisation constants: each limit is its constant unless that is
    /// `FROM_PARAMS`.
    #[inline(always)]
    pub fn from_spec(features: u32, max_bounces: u32, rr_start: u32, p: &RenderParams) -> Self {
        Self {
            features,
            max_bounces: if max_bounces == FROM_PARAMS { p.max_bounces } else { max_bounces },
            rr_start: if rr_start == FROM_PARAMS { p.rr_start } else { rr_start },
        }
    }

    /// (specialisation constant id, value) of each of the kernel's constants for this variant.
    pub fn spec_constants(self) -> [(u32, u32); 3] {
        [
            (spec_id::FEATURES, self.features),
            (spec_id::MAX_BOUNCES, self.max_bounces),
            (spec_id::RR_START, self.rr_start),
        ]
    }

    /// Whether this variant includes `bit`'s work.
    #[inline(always)]
    pub fn has(self, bit: u32) -> bool {
        self.features & bit != 0
    }

    /// Whether `kind` is the only material kind present, so material dispatch can assume it.
    #[inline(always)]
    pub fn only_material(self, kind: u32) -> bool {
        self.features & FEATURE_MATERIALS == kind
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn connections_apply_to_lambertian_rooms_lit_by_emitting_triangles() {
        let room = FEATURE_EMITTERS | FEATURE_INDIRECT | FEATURE_DIFFUSE;
        assert!(connection_applies(room));
        assert!(connection_applies(room | FEATURE_MANY_EMITTERS | FEATURE_ENVIRONMENT));
        for (why, bit) in [
            ("a conductor", FEATURE_CONDUCTOR),
            ("a dielectric", FEATURE_DIELECTRIC),
            ("a plastic", FEATURE_PLASTIC),
            ("a principled material", FEATURE_PRINCIPLED),
            ("textures", FEATURE_TEXTURES),
            ("alpha masks", FEATURE_ALPHA_MASKS),
            ("vertex normals", FEATURE_VERTEX_NORMALS),
            ("an environment map", FEATURE_ENVIRONMENT_MAP),
            ("punctual lights", FEATURE_PUNCTUAL),
        ] {
            assert!(!connection_applies(room | bit), "{why}");
        }
        for missing in [FEATURE_EMITTERS, FEATURE_INDIRECT, FEATURE_DIFFUSE] {
            assert!(!connection_applies(room & !missing), "without {missing:#b}");
        }
    }
}
