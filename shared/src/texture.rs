//! Texture lookup written out in arithmetic, not GPU samplers, so the CPU and the GPU read the
//! same value bit for bit: texel decoding from f16, repeat and clamp addressing, and bilinear
//! filtering (pbrt-v4 §10.4.3 `Image::Bilerp`; Mitsuba 3's `bitmap` texture with
//! `filter_type = "bilinear"`).
//!
//! Storage: every texture of a scene lives in one `u32` buffer. It starts with the table, four
//! words per texture (`layout::TextureInfo`: texel offset in words, width, height, flags), and
//! the texels follow. A colour texture holds linear RGBA as four IEEE half floats in two words
//! (r | g << 16, b | a << 16), 8 bytes a texel instead of f32's 16; a data texture
//! (`TEXTURE_ONE_CHANNEL`: roughness, metallic, alpha) one half float, two texels a word. The
//! host decodes sRGB to linear in f64 and rounds once, to f16 (`host::scene::texture`); here the
//! halves are widened by integer bit operations (`f16_to_f32`), exact on every device.
//!
//! Addressing: u runs left to right, v bottom to top (OBJ `vt`, Mitsuba's convention after its
//! loaders flip v), texel centres at half-integers. Repeat wraps the coordinate into [0, 1) with
//! `t − ⌊t⌋` (exact in floating point) before scaling, so the integer texel index never leaves
//! [−1, size] and no float-to-integer conversion can overflow; clamp limits it to [0, 1].
//!
//! Bilinear weights are `1 − f` and `f`, combined as (t00·(1 − fx) + t10·fx)·(1 − fy) +
//! (t01·(1 − fx) + t11·fx)·fy in that order. Products and sums only, each correctly rounded, and
//! no `a + f·(b − a)` form that a shader compiler might rewrite.
use crate::glam::{Vec2, Vec4};
use crate::layout::{TextureInfo, TEXTURE_CLAMP, TEXTURE_ONE_CHANNEL};
#[allow(unused_imports)]
use spirv_std::num_traits::Float;

/// Words per table entry (`TextureInfo`).
pub const INFO_WORDS: u32 = 4;

/// The IEEE binary16 number in the low 16 bits of `h`, widened to f32 exactly (every half is an
/// f32). Infinities and NaNs keep their class; the host stores neither.
///
/// All three cases are computed and one is picked: selects, not branches. A lookup decodes up to
/// sixteen halves and a shader holds several lookups, so three-way control flow here multiplied
/// the blocks that a driver's compiler must work through (README, "Shader size").
#[inline]
pub fn f16_to_f32(h: u32) -> f32 {
    let sign = (h & 0x8000) << 16;
    let exp = (h >> 10) & 0x1f;
    let mant = h & 0x3ff;
    // Zero or subnormal: mant · 2^-24, exact (an integer below 2^10 times a power of two that
    // stays a normal f32). The sign is applied by bits, so −0 stays −0.
    let small = (mant as f32 * (1.0 / 16_777_216.0)).to_bits() | sign;
    let special = sign | 0x7f80_0000 | (mant << 13);
    // Rebias the exponent from 15 to 127.
    let normal = sign | ((exp + 112) << 23) | (mant << 13);
    let wide = if exp == 31 { special } else { normal };
    f32::from_bits(if exp == 0 { small } else { wide })
}

/// Table entry `index` (0-based).
#[inline]
pub fn info(words: &[u32], index: u32) -> TextureInfo {
    let at = (index * INFO_WORDS) as usize;
    TextureInfo { offset: words[at], width: words[at + 1], height: words[at + 2], flags: words[at + 3] }
}

/// Texel (x, y) (row 0 at the top) as RGBA; a one-channel texel is (c, c, c, 1).
#[inline]
pub fn texel(words: &[u32], t: &TextureInfo, x: u32, y: u32) -> Vec4 {
    let i = y * t.width + x;
    if (t.flags & TEXTURE_ONE_CHANNEL) != 0 {
        let word = words[(t.offset + i / 2) as usize];
        let c = f16_to_f32(if (i & 1) == 0 { word & 0xffff } else { word >> 16 });
        Vec4::new(c, c, c, 1.0)
    } else {
        let at = (t.offset + 2 * i) as usize;
        let (rg, ba) = (words[at], words[at + 1]);
        Vec4::new(f16_to_f32(rg & 0xffff), f16_to_f32(rg >> 16), f16_to_f32(ba & 0xffff), f16_to_f32(ba >> 16))
    }
}

/// The two texel indices a bilinear lookup blends along one axis of `size` texels and the weight
/// of the second, for coordinate `t` (0 at the first edge, 1 at the far edge).
#[inline]
pub fn axis_texels(t: f32, size: u32, clamp: bool) -> (u32, u32, f32) {
    // A coordinate that is not finite (never stored, but interpolation is not trusted) reads 0.
    let t = if (t.to_bits() & 0x7f80_0000) == 0x7f80_0000 { 0.0 } else { t };
    // Comparisons written out: `f32::clamp` asserts its bounds, and a shader compiler may lower
    // it to a clamp instruction whose handling of odd inputs is the driver's.
    #[allow(clippy::manual_clamp)]
    let t = if clamp {
        if t < 0.0 {
            0.0
        } else if t > 1.0 {
            1.0
        } else {
            t
        }
    } else {
        t - t.floor()
    };
    // Texel centres at half-integers: x in [−0.5, size − 0.5].
    let x = t * size as f32 - 0.5;
    let x0 = x.floor();
    let f = x - x0;
    let i0 = x0 as i32;
    let last = size as i32 - 1;
    let (a, b) = if clamp {
        (if i0 < 0 { 0 } else { i0 }, if i0 + 1 > last { last } else { i0 + 1 })
    } else {
        (if i0 < 0 { last } else { i0 }, if i0 + 1 > last { 0 } else { i0 + 1 })
    };
    (a as u32, b as u32, f)
}

/// Texture `index`'s (0-based) bilinearly filtered value at `uv`.
///
/// The four texels are fetched in a loop, not by four calls: a shader inlines `texel` once
/// instead of four times at each of its lookups (README, "Shader size"). The blend is the same
/// products and sums in the same order (module docs).
#[inline]
pub fn sample(words: &[u32], index: u32, uv: Vec2) -> Vec4 {
    let t = info(words, index);
    let clamp = (t.flags & TEXTURE_CLAMP) != 0;
    let (x0, x1, fx) = axis_texels(uv.x, t.width, clamp);
    // Image rows run top to bottom, v bottom to top.
    let (y0, y1, fy) = axis_texels(1.0 - uv.y, t.height, clamp);
    let (wx0, wy0) = (1.0 - fx, 1.0 - fy);
    // (x0, y0), (x1, y0), (x0, y1), (x1, y1).
    let mut c = [Vec4::ZERO; 4];
    let mut k = 0;
    while k < 4 {
        let x = if (k & 1) == 0 { x0 } else { x1 };
        let y = if k < 2 { y0 } else { y1 };
        c[k] = texel(words, &t, x, y);
        k += 1;
    }
    let top = c[0] * wx0 + c[1] * fx;
    let bottom = c[2] * wx0 + c[3] * fx;
    top * wy0 + bottom * fy
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_half_widens_exactly() {
        for h in 0..=u16::MAX {
            let want = half::f16::from_bits(h).to_f32();
            let got = f16_to_f32(h as u32);
            if want.is_nan() {
                assert!(got.is_nan(), "{h:#06x}");
            } else {
                assert_eq!(got.to_bits(), want.to_bits(), "{h:#06x}: {got} vs {want}");
            }
        }
    }

    /// A table of one texture followed by its texels.
    fn texture(width: u32, height: u32, flags: u32, texels: &[[f32; 4]]) -> Vec<u32> {
        let mut words = vec![INFO_WORDS, width, height, flags];
        let h = |x: f32| half::f16::from_f32(x).to_bits() as u32;
        if flags & TEXTURE_ONE_CHANNEL != 0 {
            for pair in texels.chunks(2) {
                words.push(h(pair[0][0]) | pair.get(1).map_or(0, |t| h(t[0]) << 16));
            }
        } else {
            for t in texels {
                words.push(h(t[0]) | h(t[1]) << 16);
                words.push(h(t[2]) | h(t[3]) << 16);
            }
        }
        words
    }

    #[test]
    fn addressing_repeats_or_clamps_at_the_edges() {
        // Four texels: centres at 0.125, 0.375, 0.625, 0.875.
        assert_eq!(axis_texels(0.125, 4, false), (0, 1, 0.0));
        assert_eq!(axis_texels(0.25, 4, false), (0, 1, 0.5));
        // Left of the first centre: repeat blends the last texel in, clamp holds the first.
        assert_eq!(axis_texels(0.0, 4, false), (3, 0, 0.5));
        assert_eq!(axis_texels(0.0, 4, true), (0, 0, 0.5));
        // Right of the last centre.
        assert_eq!(axis_texels(1.0, 4, true), (3, 3, 0.5));
        assert_eq!(axis_texels(0.9375, 4, false), (3, 0, 0.25));
        // Negative and beyond one: repeat is periodic, clamp holds the edge.
        assert_eq!(axis_texels(-0.75, 4, false), axis_texels(0.25, 4, false));
        assert_eq!(axis_texels(2.25, 4, false), axis_texels(0.25, 4, false));
        assert_eq!(axis_texels(-3.0, 4, true), (0, 0, 0.5));
        assert_eq!(axis_texels(7.0, 4, true), (3, 3, 0.5));
        // Not finite: read as 0.
        assert_eq!(axis_texels(f32::NAN, 4, false), axis_texels(0.0, 4, false));
        // One texel: always that texel.
        let (a, b, _) = axis_texels(0.3, 1, false);
        assert_eq!((a, b), (0, 0));
    }

    #[test]
    fn bilinear_of_a_two_by_two_texture() {
        // Row 0 (top, v near 1): red, green; row 1 (bottom): blue, white.
        let (r, g, b, w) = ([1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 1.0], [1.0; 4]);
        let clamp = texture(2, 2, TEXTURE_CLAMP, &[r, g, b, w]);
        let at = |words: &[u32], u: f32, v: f32| sample(words, 0, Vec2::new(u, v)).to_array();
        // Texel centres give the texels.
        assert_eq!(at(&clamp, 0.25, 0.75), r);
        assert_eq!(at(&clamp, 0.75, 0.75), g);
        assert_eq!(at(&clamp, 0.25, 0.25), b);
        assert_eq!(at(&clamp, 0.75, 0.25), w);
        // The centre is the mean of the four.
        assert_eq!(at(&clamp, 0.5, 0.5), [0.5, 0.5, 0.5, 1.0]);
        // Halfway between red and green along the top row.
        assert_eq!(at(&clamp, 0.5, 0.75), [0.5, 0.5, 0.0, 1.0]);
        // A quarter of the way from red's centre to blue's: 3/4 red, 1/4 blue.
        assert_eq!(at(&clamp, 0.25, 0.625), [0.75, 0.0, 0.25, 1.0]);
        // The corner: clamped it is red; repeated it is the mean of all four.
        assert_eq!(at(&clamp, 0.0, 1.0), r);
        let repeat = texture(2, 2, 0, &[r, g, b, w]);
        assert_eq!(at(&repeat, 0.0, 1.0), [0.5, 0.5, 0.5, 1.0]);
        assert_eq!(at(&repeat, 1.25, -0.25), at(&repeat, 0.25, 0.75));
        // One channel: two texels a word.
        let grey = texture(2, 2, TEXTURE_CLAMP | TEXTURE_ONE_CHANNEL, &[[0.0; 4], [1.0; 4], [0.5; 4], [0.25; 4]]);
        assert_eq!(at(&grey, 0.75, 0.75), [1.0, 1.0, 1.0, 1.0]);
        assert_eq!(at(&grey, 0.75, 0.25), [0.25, 0.25, 0.25, 1.0]);
        assert_eq!(at(&grey, 0.5, 0.25), [0.375, 0.375, 0.375, 1.0]);
    }
}
