//! Images: PNG in 8-bit sRGB (clamped) and EXR in linear 32-bit float out, chosen by extension,
//! written through `files::write_atomic`; EXR and PFM in.
use crate::files::{self, write_atomic, MAX_IMAGE_BYTES};
use crate::settings::Aov;
use anyhow::{anyhow, bail, Result};
use std::path::Path;

/// The sRGB transfer function (IEC 61966-2-1) of a linear value, clamped to [0, 1].
pub fn linear_to_srgb(x: f32) -> f32 {
    let x = if x.is_finite() { x.clamp(0.0, 1.0) } else { 0.0 };
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// The output formats by extension; an error for anything else (checked before rendering).
pub fn check_output_path(path: &Path) -> Result<()> {
    match path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).as_deref() {
        Some("png") | Some("exr") => Ok(()),
        _ => bail!("{}: unknown image format (use .png or .exr)", path.display()),
    }
}

pub fn is_exr(path: &Path) -> bool {
    path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("exr"))
}

/// A heat map of per-pixel traversal cost (nodes + triangle tests), scaled to the image's
/// maximum, for viewing as PNG: black, blue, magenta, orange, then white for the costliest
/// pixel. The colours are linear RGB, so the PNG's sRGB encoding applies as usual.
pub fn heat_map(cost: &[[f32; 3]]) -> Vec<[f32; 3]> {
    const STOPS: [[f32; 3]; 5] =
        [[0.0, 0.0, 0.0], [0.0, 0.05, 0.6], [0.6, 0.0, 0.5], [1.0, 0.35, 0.0], [1.0, 1.0, 1.0]];
    let total = |p: &[f32; 3]| p[0] + p[1];
    let max = cost.iter().map(total).fold(0.0f32, f32::max);
    cost.iter()
        .map(|p| {
            let x = if max > 0.0 { (total(p) / max).clamp(0.0, 1.0) } else { 0.0 } * (STOPS.len() - 1) as f32;
            let i = (x.floor() as usize).min(STOPS.len() - 2);
            let f = x - i as f32;
            let (a, b) = (STOPS[i], STOPS[i + 1]);
            [a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f, a[2] + (b[2] - a[2]) * f]
        })
        .collect()
}

/// What an 8-bit image shows of an AOV's linear values: the cost as a heat map, normals as
/// 0.5 + 0.5·n (the usual normal-map encoding), radiance and albedo as they are.
pub fn for_display(aov: Aov, pixels: &[[f32; 3]]) -> Vec<[f32; 3]> {
    match aov {
        Aov::Cost => heat_map(pixels),
        Aov::Normal => pixels.iter().map(|p| p.map(|c| 0.5 + 0.5 * c)).collect(),
        Aov::Radiance | Aov::Albedo => pixels.to_vec(),
    }
}

/// Linear RGB as an 8-bit sRGB PNG in memory (what `write_image` writes to a .png).
pub fn encode_png(width: u32, height: u32, rgb: &[[f32; 3]]) -> Result<Vec<u8>> {
    if rgb.len() != width as usize * height as usize {
        bail!("{} pixels for a {width}x{height} image", rgb.len());
    }
    let bytes: Vec<u8> = rgb.iter().flat_map(|p| p.map(|c| (linear_to_srgb(c) * 255.0 + 0.5) as u8)).collect();
    let mut png = Vec::new();
    image::write_buffer_with_format(
        &mut std::io::Cursor::new(&mut png),
        &bytes,
        width,
        height,
        image::ExtendedColorType::Rgb8,
        image::ImageFormat::Png,
    )
    .map_err(|e| anyhow!("PNG: {e}"))?;
    Ok(png)
}

pub fn write_image(path: &Path, width: u32, height: u32, rgb: &[[f32; 3]]) -> Result<()> {
    if rgb.len() != (width * height) as usize {
        bail!("{}: {} pixels for a {width}x{height} image", path.display(), rgb.len());
    }
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).unwrap_or_default();
    match ext.as_str() {
        "png" => files::write_bytes(path, &encode_png(width, height, rgb)?),
        "exr" => write_atomic(path, |w| {
            use exr::prelude::*;
            let pixels = SpecificChannels::rgb(|p: Vec2<usize>| {
                let c = rgb[p.y() * width as usize + p.x()];
                (c[0], c[1], c[2])
            });
            Image::from_channels((width as usize, height as usize), pixels)
                .write()
                .to_buffered(w)
                .map_err(|e| anyhow!("EXR: {e}"))
        }),
        _ => bail!("{}: unknown image format (use .png or .exr)", path.display()),
    }
}

/// Reads a linear RGB EXR (as written by `write_image`): width, height and pixels.
pub fn read_exr(path: &Path) -> Result<(u32, u32, Vec<[f32; 3]>)> {
    use exr::prelude::*;
    files::input_size(path, MAX_IMAGE_BYTES).map_err(|e| anyhow!("{}: cannot read: {e}", path.display()))?;
    let image = read_first_rgba_layer_from_file(
        path,
        |resolution, _| (resolution.width(), vec![[0f32; 3]; resolution.width() * resolution.height()]),
        |(w, px), pos, (r, g, b, _a): (f32, f32, f32, f32)| px[pos.y() * *w + pos.x()] = [r, g, b],
    )
    .map_err(|e| anyhow!("{}: cannot read EXR: {e}", path.display()))?;
    let size = image.layer_data.size;
    Ok((size.width() as u32, size.height() as u32, image.layer_data.channel_data.pixels.1))
}

/// Reads a linear RGB image for comparison, by extension: OpenEXR (`.exr`) or Portable Float Map
/// (`.pfm`).
pub fn read_linear_image(path: &Path) -> Result<(u32, u32, Vec<[f32; 3]>)> {
    match path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).as_deref() {
        Some("exr") => read_exr(path),
        Some("pfm") => read_pfm(path),
        Some("hdr") => read_hdr(path),
        _ => bail!("{}: unknown linear image format (use .exr, .hdr or .pfm)", path.display()),
    }
}

/// Reads a Radiance RGBE picture (`.hdr`, Greg Ward's format; flat or run-length encoded rows,
/// through the `image` crate): linear RGB with an 8-bit mantissa shared by the three channels.
pub fn read_hdr(path: &Path) -> Result<(u32, u32, Vec<[f32; 3]>)> {
    let bytes =
        files::read_input(path, MAX_IMAGE_BYTES).map_err(|e| anyhow!("{}: cannot read: {e}", path.display()))?;
    let decoder = image::codecs::hdr::HdrDecoder::new(std::io::Cursor::new(&bytes[..]))
        .map_err(|e| anyhow!("{}: not a Radiance HDR file: {e}", path.display()))?;
    let meta = decoder.metadata();
    let (width, height) = (meta.width, meta.height);
    if width == 0 || height == 0 || width > crate::settings::MAX_SIDE || height > crate::settings::MAX_SIDE {
        bail!("{}: {width}×{height} pixels: each side must be 1 to {}", path.display(), crate::settings::MAX_SIDE);
    }
    let image = image::DynamicImage::from_decoder(decoder)
        .map_err(|e| anyhow!("{}: cannot decode the Radiance HDR pixels: {e}", path.display()))?;
    let texels = image.to_rgb32f().pixels().map(|p| p.0).collect();
    Ok((width, height, texels))
}

/// Reads a Portable Float Map (Paul Debevec's format as used by HDRShop and pbrt): header `PF`
/// (RGB) or `Pf` (grey, replicated to RGB), `width height`, and a scale whose sign gives the byte
/// order (negative: little-endian); then rows of f32 from the bottom row up.
pub fn read_pfm(path: &Path) -> Result<(u32, u32, Vec<[f32; 3]>)> {
    let bytes =
        files::read_input(path, MAX_IMAGE_BYTES).map_err(|e| anyhow!("{}: cannot read: {e}", path.display()))?;
    let bad = |why: &str| anyhow!("{}: not a PFM file: {why}", path.display());
    // The header is three whitespace-separated tokens after the magic, then one whitespace byte.
    let mut pos = 0usize;
    let mut tokens = Vec::new();
    while tokens.len() < 4 {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if start == pos || pos - start > 32 {
            return Err(bad("truncated or malformed header"));
        }
        tokens.push(std::str::from_utf8(&bytes[start..pos]).map_err(|_| bad("header is not text"))?);
    }
    pos += 1; // the single whitespace byte that ends the header
    let channels = match tokens[0] {
        "PF" => 3,
        "Pf" => 1,
        _ => return Err(bad("magic is neither PF nor Pf")),
    };
    let width: u32 = tokens[1].parse().map_err(|_| bad("width is not a number"))?;
    let height: u32 = tokens[2].parse().map_err(|_| bad("height is not a number"))?;
    let scale: f32 = tokens[3].parse().map_err(|_| bad("scale is not a number"))?;
    if width == 0 || height == 0 || width > crate::settings::MAX_SIDE || height > crate::settings::MAX_SIDE {
        return Err(bad(&format!("size {width}x{height} out of range")));
    }
    if !(scale.is_finite() && scale != 0.0) {
        return Err(bad("scale must be finite and non-zero"));
    }
    let n = width as usize * height as usize;
    let need = n * channels * 4;
    let data = bytes
        .get(pos..)
        .filter(|d| d.len() >= need)
        .ok_or_else(|| bad(&format!("{} bytes of pixel data, expected {need}", bytes.len().saturating_sub(pos))))?;
    let value = |i: usize| {
        let b = [data[4 * i], data[4 * i + 1], data[4 * i + 2], data[4 * i + 3]];
        if scale < 0.0 {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        }
    };
    let mut pixels = vec![[0f32; 3]; n];
    for y in 0..height as usize {
        // File rows run bottom to top; ours top to bottom.
        let row = height as usize - 1 - y;
        for x in 0..width as usize {
            let i = (y * width as usize + x) * channels;
            pixels[row * width as usize + x] =
                if channels == 3 { [value(i), value(i + 1), value(i + 2)] } else { [value(i); 3] };
        }
    }
    Ok((width, height, pixels))
}

/// Writes a little-endian RGB Portable Float Map (the inverse of `read_pfm`).
pub fn write_pfm(path: &Path, width: u32, height: u32, rgb: &[[f32; 3]]) -> Result<()> {
    if rgb.len() != (width * height) as usize {
        bail!("{}: {} pixels for a {width}x{height} image", path.display(), rgb.len());
    }
    let mut out = format!("PF\n{width} {height}\n-1.0\n").into_bytes();
    for y in (0..height as usize).rev() {
        for p in &rgb[y * width as usize..(y + 1) * width as usize] {
            for c in p {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    files::write_bytes(path, &out)
}
