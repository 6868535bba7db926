//! Punctual lights (glTF `KHR_lights_punctual`): point and spot lights of intensity I (candela)
//! and directional lights of illuminance E (lux). Delta lights: next-event estimation samples
//! them, BSDF rays never hit them. Each is a `layout::PunctualLight` of 16 words in the texture
//! buffer, found through its light-table entry.
use crate::glam::Vec3;
use crate::layout::{PunctualLight, PUNCTUAL_DIRECTIONAL, PUNCTUAL_SPOT};
use crate::vecmath::dot;
#[allow(unused_imports)]
use spirv_std::num_traits::Float;

/// Words a `PunctualLight` takes in the texture buffer.
pub const WORDS: u32 = 16;

#[inline(always)]
fn f(words: &[u32], i: u32) -> f32 {
    f32::from_bits(words[i as usize])
}

#[inline(always)]
fn v3(words: &[u32], i: u32) -> Vec3 {
    Vec3::new(f(words, i), f(words, i + 1), f(words, i + 2))
}

/// The light at word `o` (the layout of `PunctualLight`).
#[inline]
pub fn load(words: &[u32], o: u32) -> PunctualLight {
    let p = v3(words, o);
    let d = v3(words, o + 4);
    let i = v3(words, o + 8);
    PunctualLight {
        position: [p.x, p.y, p.z],
        kind: words[o as usize + 3],
        direction: [d.x, d.y, d.z],
        _pad0: 0,
        intensity: [i.x, i.y, i.z],
        _pad1: 0,
        cone_scale: f(words, o + 12),
        cone_offset: f(words, o + 13),
        _pad2: [0; 2],
    }
}

/// What a punctual light sends to a point: the unit direction toward it, the incident radiance
/// as a delta (irradiance at normal incidence: I/d² or E) and whether the shadow ray ends at
/// `target` (point, spot) or runs to infinity along `wi` (directional).
#[derive(Clone, Copy)]
pub struct PunctualSample {
    pub wi: Vec3,
    pub incident: Vec3,
    pub target: Vec3,
    pub infinite: bool,
}

/// glTF's spot falloff: clamp(cos·scale + offset, 0, 1)².
#[inline]
#[allow(clippy::manual_clamp)]
pub fn spot_falloff(l: &PunctualLight, cos: f32) -> f32 {
    let a = cos * l.cone_scale + l.cone_offset;
    let a = if a < 0.0 {
        0.0
    } else if a > 1.0 {
        1.0
    } else {
        a
    };
    a * a
}

/// The light at word `o` seen from `pos`.
#[inline]
pub fn sample(words: &[u32], o: u32, pos: Vec3) -> PunctualSample {
    let l = load(words, o);
    let intensity = Vec3::new(l.intensity[0], l.intensity[1], l.intensity[2]);
    let dir = Vec3::new(l.direction[0], l.direction[1], l.direction[2]);
    if l.kind == PUNCTUAL_DIRECTIONAL {
        return PunctualSample { wi: -dir, incident: intensity, target: pos, infinite: true };
    }
    let p = Vec3::new(l.position[0], l.position[1], l.position[2]);
    let to = p - pos;
    let d2 = dot(to, to);
    let inv = if d2 > 0.0 { 1.0 / d2.sqrt() } else { 0.0 };
    let wi = to * inv;
    let mut scale = if d2 > 0.0 { 1.0 / d2 } else { 0.0 };
    if l.kind == PUNCTUAL_SPOT {
        scale *= spot_falloff(&l, -dot(wi, dir));
    }
    PunctualSample { wi, incident: intensity * scale, target: p, infinite: false }
}
