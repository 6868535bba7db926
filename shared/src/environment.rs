//! The environment map: an equirectangular (latitude-longitude) HDR image of the radiance arriving
//! from every direction, looked up and importance-sampled from the texture buffer.
//!
//! Mapping (Mitsuba 3's `envmap`, `src/emitters/envmap.cpp`): a world direction is turned into
//! the map's frame by the inverse of its `to_world` rotation; there, for a unit direction
//! d = (x, y, z), u = atan2(x, −z) / 2π (wrapped into [0, 1)) and v = acos(y) / π, so +Y is the
//! top row (v = 0), and d = (sin φ sin θ, cos θ, −cos φ sin θ) for φ = 2πu, θ = πv. Radiance is
//! interpolated bilinearly as Mitsuba does: column x is centred on u = (x + ½)/W and wraps
//! around; row y lies at v = y/(H − 1) (the first and last rows at the poles), clamped.
//!
//! Sampling: a piecewise-constant distribution over W × H cells of the (u, v) square (cell (x, y)
//! covers [x/W, (x+1)/W) × [y/H, (y+1)/H)), weighted by the mean luminance of the texels that
//! bilinear lookups in the cell read times sin θ at its centre (pbrt-v4, Mitsuba): a marginal
//! CDF over rows, a conditional CDF per row, built by the host in f64 and rounded once. The
//! solid-angle density of a direction is pdf_uv / (2π² sin θ).
//!
//! Every scale that involves a constant (W/2π, 1/2π², …) is computed by the host and read from
//! the header: Mesa reassociates products with constants, so a product like atan2(·)·(1/2π)·W
//! would round differently on lavapipe.
//!
//! Layout at word `o` of the texture buffer (f32 as bits unless said):
//! | words | what |
//! |---|---|
//! | o, o+1 | W, H (u32) |
//! | o+2 | the map's probability in the light-selection distribution |
//! | o+3 | (H − 1)/H |
//! | o+4 .. o+13 | `to_world` rotation, rows (9 floats) |
//! | o+13, o+14, o+15 | W/2π, (H − 1)/π, H/π |
//! | o+16, o+17 | 1/W, 1/H |
//! | o+18 | π/2 (`trig::sincos_turns_with`) |
//! | o+19 | ½ (the column centre offset, read so that no driver folds it into a sum) |
//! | `HEADER_WORDS` .. +H+1 | marginal CDF over rows (0 … 1) |
//! | then H × (W+1) | conditional CDF of each row |
//! | then W × H | pdf_uv of each cell (its probability × W·H) / 2π² |
//! | then W × H × 3 | texels, RGB × strength, row by row from the top |
use crate::glam::Vec3;
use crate::sampling::remap_between;
use crate::trig::{atan2, sincos_turns_with};
#[allow(unused_imports)]
use spirv_std::num_traits::Float;

/// Words before the marginal CDF.
pub const HEADER_WORDS: u32 = 20;

/// Total words of a W × H map.
pub const fn words(w: u32, h: u32) -> u32 {
    HEADER_WORDS + (h + 1) + h * (w + 1) + w * h + 3 * w * h
}

#[inline(always)]
fn f(words: &[u32], i: u32) -> f32 {
    f32::from_bits(words[i as usize])
}

/// The map's selection probability (`Light::pmf` of its entry).
#[inline]
pub fn selection_pmf(words: &[u32], o: u32) -> f32 {
    f(words, o + 2)
}

#[inline]
fn row(words: &[u32], o: u32, r: u32) -> Vec3 {
    Vec3::new(f(words, o + 4 + 3 * r), f(words, o + 5 + 3 * r), f(words, o + 6 + 3 * r))
}

/// The map's frame: `to_world` times `d`.
#[inline]
fn to_world(words: &[u32], o: u32, d: Vec3) -> Vec3 {
    let (a, b, c) = (row(words, o, 0), row(words, o, 1), row(words, o, 2));
    Vec3::new(a.x * d.x + a.y * d.y + a.z * d.z, b.x * d.x + b.y * d.y + b.z * d.z, c.x * d.x + c.y * d.y + c.z * d.z)
}

/// The inverse (transpose) of `to_world` times `d`.
#[inline]
fn to_local(words: &[u32], o: u32, d: Vec3) -> Vec3 {
    let (a, b, c) = (row(words, o, 0), row(words, o, 1), row(words, o, 2));
    Vec3::new(a.x * d.x + b.x * d.y + c.x * d.z, a.y * d.x + b.y * d.y + c.y * d.z, a.z * d.x + b.z * d.y + c.z * d.z)
}

/// Where a world direction falls on the map (`locate`): its column coordinate u·W, its row
/// coordinates θ·(H − 1)/π for a lookup (`radiance`) and θ·H/π for the density (`density`), and
/// sin θ.
#[derive(Clone, Copy)]
pub struct MapPoint {
    cu: f32,
    fy: f32,
    rv: f32,
    sin_theta: f32,
}

/// Where world direction `dir` (need not be unit) falls on map `o`: one conversion (two
/// arctangents) for its radiance and its density, which a shader would otherwise inline twice.
#[inline]
pub fn locate(words: &[u32], o: u32, dir: Vec3) -> MapPoint {
    let d = to_local(words, o, dir);
    let w = words[o as usize] as f32;
    let rho = (d.x * d.x + d.z * d.z).sqrt();
    // Not sqrt(rho² + y²): a driver may replace sqrt(a)·sqrt(a) by a.
    let len = (d.x * d.x + d.y * d.y + d.z * d.z).sqrt();
    let mut cu = atan2(d.x, -d.z) * f(words, o + 13);
    if cu < 0.0 {
        cu += w;
    }
    if cu >= w {
        cu = 0.0;
    }
    let theta = atan2(rho, d.y);
    let (fy, rv) = (theta * f(words, o + 14), theta * f(words, o + 15));
    let sin_theta = if len > 0.0 { rho / len } else { 0.0 };
    MapPoint { cu, fy: if fy > 0.0 { fy } else { 0.0 }, rv: if rv > 0.0 { rv } else { 0.0 }, sin_theta }
}

/// a + (b − a)·t per channel, in scalars: a vector multiply-add here came out fused on lavapipe
/// (an ulp off the CPU), the scalar form does not.
#[inline(always)]
fn lerp(a: Vec3, b: Vec3, t: f32) -> Vec3 {
    Vec3::new(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t, a.z + (b.z - a.z) * t)
}

#[inline]
fn texel(words: &[u32], base: u32, w: u32, x: u32, y: u32) -> Vec3 {
    let i = base + 3 * (y * w + x);
    Vec3::new(f(words, i), f(words, i + 1), f(words, i + 2))
}

// Comparisons, not `clamp`/`saturating_sub`: the same selects on both devices.
#[allow(clippy::manual_clamp, clippy::implicit_saturating_sub)]
/// Radiance at column coordinate `cu` = u·W and row coordinate `fy` = v·(H − 1), bilinearly
/// interpolated as Mitsuba's `envmap` does.
#[inline]
pub fn eval_at(words: &[u32], o: u32, cu: f32, fy: f32) -> Vec3 {
    let w = words[o as usize];
    let h = words[o as usize + 1];
    let base = o + HEADER_WORDS + (h + 1) + h * (w + 1) + w * h;
    // Columns: centred on (x + ½)/W, wrapping. fx + 1 ≥ ½, so truncation is floor.
    let fx1 = cu + f(words, o + 19);
    let x1 = fx1 as u32;
    let tx = fx1 - x1 as f32;
    let xa = if x1 == 0 { w - 1 } else { x1 - 1 };
    let xb = if x1 >= w { 0 } else { x1 };
    // Rows at v = y / (H − 1), clamped.
    let mut y0 = fy as u32;
    if y0 + 1 >= h {
        y0 = if h >= 2 { h - 2 } else { 0 };
    }
    let y1 = if h >= 2 { y0 + 1 } else { 0 };
    let ty0 = fy - y0 as f32;
    let ty = if ty0 < 0.0 {
        0.0
    } else if ty0 > 1.0 {
        1.0
    } else {
        ty0
    };
    let top = lerp(texel(words, base, w, xa, y0), texel(words, base, w, xb, y0), tx);
    let bottom = lerp(texel(words, base, w, xa, y1), texel(words, base, w, xb, y1), tx);
    lerp(top, bottom, ty)
}

/// Radiance arriving from world direction `dir` (need not be unit).
#[inline]
pub fn eval(words: &[u32], o: u32, dir: Vec3) -> Vec3 {
    radiance(words, o, &locate(words, o, dir))
}

/// Radiance arriving from the direction that falls on `at`.
#[inline]
pub fn radiance(words: &[u32], o: u32, at: &MapPoint) -> Vec3 {
    eval_at(words, o, at.cu, at.fy)
}

/// Solid-angle density of sampling world direction `dir` (`sample`), without the selection
/// probability.
#[inline]
pub fn pdf(words: &[u32], o: u32, dir: Vec3) -> f32 {
    density(words, o, &locate(words, o, dir))
}

/// `pdf` of the direction that falls on `at`.
#[inline]
pub fn density(words: &[u32], o: u32, at: &MapPoint) -> f32 {
    if at.sin_theta <= 0.0 {
        return 0.0;
    }
    let w = words[o as usize];
    let h = words[o as usize + 1];
    let cx = at.cu as u32;
    let cy = at.rv as u32;
    let cx = if cx >= w { w - 1 } else { cx };
    let cy = if cy >= h { h - 1 } else { cy };
    let cells = o + HEADER_WORDS + (h + 1) + h * (w + 1);
    f(words, cells + cy * w + cx) / at.sin_theta
}

/// Index i in [0, n) with cdf[i] ≤ u < cdf[i+1] (the CDF at words `c` .. `c + n + 1`), skipping
/// empty intervals.
#[inline]
fn search(words: &[u32], c: u32, n: u32, u: f32) -> u32 {
    let mut lo = 0u32;
    let mut hi = n - 1;
    while lo < hi {
        let mid = (lo + hi) / 2;
        if u < f(words, c + mid + 1) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo
}

/// `u` rescaled within [cdf[i], cdf[i+1]) to [0, 1).
#[inline]
fn remap(words: &[u32], c: u32, i: u32, u: f32) -> f32 {
    remap_between(f(words, c + i), f(words, c + i + 1), u)
}

/// A sampled direction toward the environment: world direction (unit), the radiance from it and
/// the solid-angle density (0: invalid), without the selection probability.
#[derive(Clone, Copy)]
pub struct EnvironmentSample {
    pub wi: Vec3,
    pub radiance: Vec3,
    pub pdf: f32,
}

/// Samples a direction in proportion to the cell distribution: `u2` picks the row, `u1` the
/// column; each rescaled within its interval places the point in the cell.
#[inline]
pub fn sample(words: &[u32], o: u32, u1: f32, u2: f32) -> EnvironmentSample {
    let w = words[o as usize];
    let h = words[o as usize + 1];
    let marginal = o + HEADER_WORDS;
    let y = search(words, marginal, h, u2);
    let fy = remap(words, marginal, y, u2);
    let conditional = marginal + (h + 1) + y * (w + 1);
    let x = search(words, conditional, w, u1);
    let fx = remap(words, conditional, x, u1);
    let cu = x as f32 + fx;
    let rv = y as f32 + fy;
    let u = cu * f(words, o + 16);
    let v = rv * f(words, o + 17);
    let half_pi = f(words, o + 18);
    let (sin_phi, cos_phi) = sincos_turns_with(u, half_pi);
    let (sin_theta, cos_theta) = sincos_turns_with(v * 0.5, half_pi);
    let local = Vec3::new(sin_phi * sin_theta, cos_theta, -(cos_phi * sin_theta));
    let cells = marginal + (h + 1) + h * (w + 1);
    let pdf = if sin_theta > 0.0 { f(words, cells + y * w + x) / sin_theta } else { 0.0 };
    EnvironmentSample { wi: to_world(words, o, local), radiance: eval_at(words, o, cu, rv * f(words, o + 3)), pdf }
}
