//! Image output: PNG in 8-bit sRGB (clamped) and EXR in linear 32-bit float, chosen by extension.
use anyhow::{anyhow, bail, Context, Result};
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
    const STOPS: [[f32; 3]; 5] = [[0.0, 0.0, 0.0], [0.0, 0.05, 0.6], [0.6, 0.0, 0.5], [1.0, 0.35, 0.0], [1.0, 1.0, 1.0]];
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

pub fn write_image(path: &Path, width: u32, height: u32, rgb: &[[f32; 3]]) -> Result<()> {
    if rgb.len() != (width * height) as usize {
        bail!("{}: {} pixels for a {width}x{height} image", path.display(), rgb.len());
    }
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).unwrap_or_default();
    match ext.as_str() {
        "png" => {
            let bytes: Vec<u8> = rgb.iter().flat_map(|p| p.map(|c| (linear_to_srgb(c) * 255.0 + 0.5) as u8)).collect();
            image::save_buffer_with_format(path, &bytes, width, height, image::ExtendedColorType::Rgb8, image::ImageFormat::Png).with_context(|| format!("{}: cannot write PNG", path.display()))
        }
        "exr" => exr::prelude::write_rgb_file(path, width as usize, height as usize, |x, y| {
            let p = rgb[y * width as usize + x];
            (p[0], p[1], p[2])
        })
        .map_err(|e| anyhow!("{}: cannot write EXR: {e}", path.display())),
        _ => bail!("{}: unknown image format (use .png or .exr)", path.display()),
    }
}

/// Reads a linear RGB EXR (as written by `write_image`): width, height and pixels.
pub fn read_exr(path: &Path) -> Result<(u32, u32, Vec<[f32; 3]>)> {
    use exr::prelude::*;
    let image = read_first_rgba_layer_from_file(
        path,
        |resolution, _| (resolution.width(), vec![[0f32; 3]; resolution.width() * resolution.height()]),
        |(w, px), pos, (r, g, b, _a): (f32, f32, f32, f32)| px[pos.y() * *w + pos.x()] = [r, g, b],
    )
    .map_err(|e| anyhow!("{}: cannot read EXR: {e}", path.display()))?;
    let size = image.layer_data.size;
    Ok((size.width() as u32, size.height() as u32, image.layer_data.channel_data.pixels.1))
}
