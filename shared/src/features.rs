//! What a scene uses, as bits of one `u32`: the form a specialised variant of the integrator is
//! chosen by on either device (a rust-gpu specialisation constant is a `u32`, a CPU variant a
//! const generic). The host finds the set when it loads a scene (`host::render::features`).
//! Each bit is a thing some scenes do not need: a variant compiled without it skips that work.

/// At least one emitting triangle: next-event estimation and MIS have something to sample.
pub const FEATURE_EMITTERS: u32 = 1 << 0;
/// More than one emitting triangle: picking a light needs the light table's distribution.
pub const FEATURE_MANY_EMITTERS: u32 = 1 << 1;
/// Rays that leave the scene bring radiance (a non-black environment).
pub const FEATURE_ENVIRONMENT: u32 = 1 << 2;
/// Lambertian diffuse materials are present (one bit per material kind from here on).
pub const FEATURE_DIFFUSE: u32 = 1 << 3;
/// Light can reach the camera after a bounce: there is a source, a reflecting material and at
/// least one bounce allowed. Without it a path ends at its first hit.
pub const FEATURE_INDIRECT: u32 = 1 << 4;
/// Every feature: the generic code, which serves any scene.
pub const FEATURES_ALL: u32 = (1 << 5) - 1;
