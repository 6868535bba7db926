//! Texture images: PNG and JPEG decoded through `image`, converted to linear values and packed
//! into the one texture buffer that both renderers read (`shared::texture` has the layout and
//! the lookup).
//!
//! Colour textures (albedo, emission) are sRGB-encoded images: each 8- or 16-bit channel value
//! c is decoded with the sRGB transfer function (IEC 61966-2-1: c/12.92 below 0.04045, else
//! ((c + 0.055)/1.055)^2.4) in f64 and rounded once, to an IEEE half float; alpha is linear.
//! Data textures (roughness, metallic, alpha masks) are linear: their first channel (an alpha
//! mask its alpha channel, where the image has one), rounded once to a half. Halves keep 11
//! significant bits, more than an 8-bit sRGB value needs to round-trip (its smallest step,
//! between 0 and 1/255 in sRGB, is 3e-4 linear; a half near there resolves 6e-8).
//!
//! Every error names the image and what asked for it (the MTL file and line, or the scene
//! file's key); nothing here panics on a bad file.
use crate::files::Files;
use anyhow::{anyhow, bail, Result};
use shared::layout::{TextureInfo, TEXTURE_CLAMP, TEXTURE_ONE_CHANNEL};
use shared::texture::INFO_WORDS;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// How a texture's values are read from its image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kind {
    /// sRGB colour, RGBA.
    Colour,
    /// A linear value: the first channel.
    Value,
    /// A linear alpha mask: the alpha channel, or the first channel of an image without one (or
    /// whose alpha is opaque everywhere).
    Alpha,
    /// glTF: sRGB colour times a linear factor per channel (the bits of three f32s: a
    /// baseColorFactor, an emissiveFactor × strength), RGBA (alpha as read).
    ColourTimes([u32; 3]),
    /// glTF: linear RGBA as stored (a normal map).
    Linear,
    /// glTF: linear channel `c` (0 = R … 3 = A; an image without alpha reads 1 there) times a
    /// factor (the bits of an f32): metallic (B), roughness (G), an alpha mask (A).
    ChannelTimes(u8, u32),
}

impl Kind {
    /// Four halves a texel (RGBA) rather than one.
    pub fn is_colour(self) -> bool {
        matches!(self, Kind::Colour | Kind::ColourTimes(_) | Kind::Linear)
    }
}

/// A decoded texture: linear values as half floats, four per texel (colour) or one (data), rows
/// top to bottom.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// The image file, for messages and `--json`.
    pub source: PathBuf,
    pub width: u32,
    pub height: u32,
    pub kind: Kind,
    /// Clamp addressing (`TEXTURE_CLAMP`) rather than repeat.
    pub clamp: bool,
    pub halves: Vec<u16>,
}

impl Texture {
    /// The mean linear RGB over all texels (a data texture's value in all three).
    pub fn mean_rgb(&self) -> [f32; 3] {
        let per = if self.kind.is_colour() { 4 } else { 1 };
        let mut sum = [0f64; 3];
        for texel in self.halves.chunks(per) {
            for (c, s) in sum.iter_mut().enumerate() {
                *s += half::f16::from_bits(texel[c.min(per - 1)]).to_f64();
            }
        }
        let n = (self.halves.len() / per).max(1) as f64;
        sum.map(|s| (s / n) as f32)
    }
}

/// The sRGB transfer function's inverse (IEC 61966-2-1), for a value in 0..=1.
pub fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The most texels one texture may have (16384²): more would not fit a GPU buffer anyway.
pub const MAX_TEXELS: u64 = 1 << 28;

/// Decodes the image `bytes` (`source` names it) as a texture of `kind`.
pub fn decode(source: &Path, bytes: &[u8], kind: Kind) -> Result<Texture> {
    let image = image::load_from_memory(bytes)
        .map_err(|e| anyhow!("{}: not a PNG or JPEG image this build can decode: {e}", source.display()))?;
    let (width, height) = (image.width(), image.height());
    if width == 0 || height == 0 || width as u64 * height as u64 > MAX_TEXELS {
        bail!("{}: image of {width}×{height} texels: textures need 1 to {MAX_TEXELS} texels", source.display());
    }
    // 16 bits per channel: 8-bit values scale exactly (v · 257), so v/255 = w/65535.
    let rgba = image.into_rgba16();
    // A mask is the alpha channel where it says something (an image saved with an alpha
    // channel that is opaque everywhere is a grey mask in RGBA).
    let has_alpha = rgba.pixels().any(|p| p.0[3] != u16::MAX);
    let unit = |v: u16| v as f64 / 65535.0;
    let half = |x: f64| half::f16::from_f64(x).to_bits();
    let halves: Vec<u16> = match kind {
        Kind::Colour => rgba
            .pixels()
            .flat_map(|p| {
                let [r, g, b, a] = p.0;
                [
                    half(srgb_to_linear(unit(r))),
                    half(srgb_to_linear(unit(g))),
                    half(srgb_to_linear(unit(b))),
                    half(unit(a)),
                ]
            })
            .collect(),
        Kind::Value => rgba.pixels().map(|p| half(unit(p.0[0]))).collect(),
        Kind::Alpha => rgba.pixels().map(|p| half(unit(if has_alpha { p.0[3] } else { p.0[0] }))).collect(),
        Kind::ColourTimes(f) => {
            let f = f.map(|b| f32::from_bits(b) as f64);
            rgba.pixels()
                .flat_map(|p| {
                    let [r, g, b, a] = p.0;
                    [
                        half(srgb_to_linear(unit(r)) * f[0]),
                        half(srgb_to_linear(unit(g)) * f[1]),
                        half(srgb_to_linear(unit(b)) * f[2]),
                        half(unit(a)),
                    ]
                })
                .collect()
        }
        Kind::Linear => rgba.pixels().flat_map(|p| p.0.map(|v| half(unit(v)))).collect(),
        Kind::ChannelTimes(c, f) => {
            let (c, f) = ((c as usize).min(3), f32::from_bits(f) as f64);
            rgba.pixels().map(|p| half(unit(p.0[c]) * f)).collect()
        }
    };
    if halves.iter().any(|&h| !half::f16::from_bits(h).is_finite()) {
        bail!("{}: texel values beyond a half float's range once scaled", source.display());
    }
    Ok(Texture { source: source.to_path_buf(), width, height, kind, clamp: false, halves })
}

/// The texture buffer: the table (`TextureInfo`, four words each), then each texture's texels
/// (`shared::texture`). Repeat addressing throughout (OBJ and Mitsuba's default).
pub fn pack(textures: &[Texture]) -> Result<Vec<u32>> {
    let mut words: Vec<u32> = vec![0; textures.len() * INFO_WORDS as usize];
    for (i, t) in textures.iter().enumerate() {
        let offset = u32::try_from(words.len()).map_err(|_| anyhow!("textures: more than 16 GiB in all"))?;
        let one = !t.kind.is_colour();
        let flags = if one { TEXTURE_ONE_CHANNEL } else { 0 } | if t.clamp { TEXTURE_CLAMP } else { 0 };
        let info = TextureInfo { offset, width: t.width, height: t.height, flags };
        words[i * 4..i * 4 + 4].copy_from_slice(&[info.offset, info.width, info.height, info.flags]);
        for pair in t.halves.chunks(2) {
            words.push(pair[0] as u32 | (pair.get(1).copied().unwrap_or(0) as u32) << 16);
        }
    }
    u32::try_from(words.len()).map_err(|_| anyhow!("textures: more than 16 GiB in all"))?;
    Ok(words)
}

/// Checks a texture buffer of `count` textures (from a `.kdc` file): every table entry's texels
/// lie within the buffer after the table. What `shared::texture` may then index safely.
/// Words of a texture buffer that its `count` textures take (table and texels; what follows
/// is the rough plastics' coating tables, `coating`). The buffer must have passed `check_packed`.
pub fn packed_len(words: &[u32], count: usize) -> usize {
    (0..count)
        .map(|i| {
            let [offset, width, height, flags] = [0, 1, 2, 3].map(|k| words[i * 4 + k] as usize);
            let texels = width * height;
            offset + if flags & TEXTURE_ONE_CHANNEL as usize != 0 { texels.div_ceil(2) } else { 2 * texels }
        })
        .fold(count * INFO_WORDS as usize, usize::max)
}

pub fn check_packed(words: &[u32], count: usize) -> Result<()> {
    let table = count.checked_mul(INFO_WORDS as usize).ok_or_else(|| anyhow!("texture count overflows"))?;
    if table > words.len() {
        bail!("{count} textures need a {table}-word table, the buffer holds {} words", words.len());
    }
    for i in 0..count {
        let [offset, width, height, flags] = [0, 1, 2, 3].map(|k| words[i * 4 + k] as u64);
        let texels = width * height;
        if width == 0 || height == 0 || texels > MAX_TEXELS || flags > 3 {
            bail!("texture {i}: {width}×{height} texels, flags {flags}: not a valid texture");
        }
        let needed = if flags & TEXTURE_ONE_CHANNEL as u64 != 0 { texels.div_ceil(2) } else { 2 * texels };
        if offset < table as u64 || offset + needed > words.len() as u64 {
            bail!(
                "texture {i}: texels at words {offset}..{} outside the buffer ({} words)",
                offset + needed,
                words.len()
            );
        }
    }
    Ok(())
}

/// The textures of a scene as they are loaded, each image decoded once per kind.
#[derive(Clone, Debug, Default)]
pub struct TextureSet {
    pub textures: Vec<Texture>,
    index: HashMap<(PathBuf, Kind, bool), u32>,
}

impl TextureSet {
    /// The slot value (`shared::layout::Material::textures`: 1 + index) of the image at `path`
    /// read as `kind`, decoding it on first use. `wanted_by` names what asked for it (a file and
    /// line and key) for messages.
    pub fn load(&mut self, files: &dyn Files, path: &Path, kind: Kind, wanted_by: &str) -> Result<u32> {
        if let Some(&i) = self.index.get(&(path.to_path_buf(), kind, false)) {
            return Ok(i + 1);
        }
        let bytes =
            files.read(path).map_err(|e| anyhow!("{wanted_by}: texture {}: cannot read: {e}", path.display()))?;
        self.load_bytes(path, || Ok(bytes), kind, false, wanted_by)
    }

    /// `load` for an image whose bytes `bytes` gives (read only on first use), known by the name
    /// `source` (a file, or a glTF file's embedded image), with clamp or repeat addressing.
    pub fn load_bytes(
        &mut self,
        source: &Path,
        bytes: impl FnOnce() -> Result<Vec<u8>>,
        kind: Kind,
        clamp: bool,
        wanted_by: &str,
    ) -> Result<u32> {
        let key = (source.to_path_buf(), kind, clamp);
        if let Some(&i) = self.index.get(&key) {
            return Ok(i + 1);
        }
        let bytes = bytes()?;
        let mut texture = decode(source, &bytes, kind).map_err(|e| anyhow!("{wanted_by}: texture {e}"))?;
        texture.clamp = clamp;
        let i = self.textures.len() as u32;
        self.textures.push(texture);
        self.index.insert(key, i);
        Ok(i + 1)
    }

    /// Adds another set's textures after this one's; returns how far its slot values move.
    pub fn append(&mut self, other: TextureSet) -> u32 {
        let shift = self.textures.len() as u32;
        self.textures.extend(other.textures);
        shift
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_decodes_by_the_formula() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-15);
        // The linear segment and the power segment meet at 0.04045.
        assert!((srgb_to_linear(0.04045) - 0.04045 / 12.92).abs() < 1e-15);
        assert!((srgb_to_linear(0.5) - 0.214_041_140_482_232_5).abs() < 1e-12);
        let png = |pixels: &[[u8; 4]], w: u32| {
            let img = image::RgbaImage::from_raw(w, pixels.len() as u32 / w, pixels.concat()).unwrap();
            let mut bytes = Vec::new();
            img.write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png).unwrap();
            bytes
        };
        let bytes = png(&[[128, 10, 255, 51]], 1);
        let t = decode(Path::new("x.png"), &bytes, Kind::Colour).unwrap();
        let want = [srgb_to_linear(128.0 / 255.0), srgb_to_linear(10.0 / 255.0), 1.0, 0.2];
        for (h, w) in t.halves.iter().zip(want) {
            assert_eq!(*h, half::f16::from_f64(w).to_bits());
        }
        // Data: the first channel, linear; a mask its alpha.
        let t = decode(Path::new("x.png"), &bytes, Kind::Value).unwrap();
        assert_eq!(t.halves, [half::f16::from_f64(128.0 / 255.0).to_bits()]);
        let t = decode(Path::new("x.png"), &bytes, Kind::Alpha).unwrap();
        assert_eq!(t.halves, [half::f16::from_f64(0.2).to_bits()]);
        assert!(decode(Path::new("broken.png"), b"not an image", Kind::Colour)
            .unwrap_err()
            .to_string()
            .contains("broken.png"));
    }

    #[test]
    fn packing_lays_out_the_table_and_checks_it() {
        let t = |w, h, kind| Texture {
            source: "t".into(),
            width: w,
            height: h,
            kind,
            clamp: false,
            halves: vec![0x3c00; (w * h * if kind == Kind::Colour { 4 } else { 1 }) as usize],
        };
        let words = pack(&[t(2, 1, Kind::Colour), t(3, 1, Kind::Value)]).unwrap();
        assert_eq!(&words[..8], &[8, 2, 1, 0, 12, 3, 1, TEXTURE_ONE_CHANNEL]);
        assert_eq!(words.len(), 8 + 4 + 2);
        check_packed(&words, 2).unwrap();
        assert!(check_packed(&words[..13], 2).is_err());
        assert!(check_packed(&words, 4).is_err());
    }
}
