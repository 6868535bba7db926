//! A glTF metallic-roughness material onto `principled`: its textures' image bytes, factors and
//! channels, emission, transmission, ior and alpha.
#[allow(unused_imports)]
use super::*;

/// Reads an image's bytes when first needed.
pub(super) type ImageBytes<'a> = Box<dyn FnOnce() -> Result<Vec<u8>> + 'a>;

/// The image bytes of a texture and a name for it (its file, or `file.gltf#image3`).
pub(super) fn image_source<'a>(
    path: &'a Path,
    buffers: &'a [Vec<u8>],
    files: &'a dyn Files,
    image: &::gltf::Image,
) -> (PathBuf, ImageBytes<'a>) {
    match image.source() {
        ::gltf::image::Source::Uri { uri, .. } if !uri.starts_with("data:") => {
            let full = path.parent().unwrap_or(Path::new("")).join(percent_decode(uri));
            let uri = uri.to_string();
            let f = full.clone();
            (
                full,
                Box::new(move || {
                    files
                        .read(&f)
                        .map_err(|e| anyhow!("{}: image {uri:?}: cannot read {}: {e}", path.display(), f.display()))
                }),
            )
        }
        ::gltf::image::Source::Uri { uri, .. } => {
            let name = PathBuf::from(format!("{}#image{}", path.display(), image.index()));
            let uri = uri.to_string();
            let what = format!("image {}", image.index());
            (name, Box::new(move || read_uri(path, &uri, files, &what)))
        }
        ::gltf::image::Source::View { view, .. } => {
            let name = PathBuf::from(format!("{}#image{}", path.display(), image.index()));
            let (b, start, len, index) = (view.buffer().index(), view.offset(), view.length(), image.index());
            (
                name,
                Box::new(move || {
                    buffers
                        .get(b)
                        .and_then(|data| data.get(start..start.checked_add(len)?))
                        .map(<[u8]>::to_vec)
                        .ok_or_else(|| {
                            anyhow!("{}: image {index}: its buffer view lies outside buffer {b}", path.display())
                        })
                }),
            )
        }
    }
}

/// A glTF material as a principled one (module docs; README "glTF scenes").
#[allow(clippy::too_many_arguments)]
pub(super) fn material(
    path: &Path,
    document: &::gltf::Document,
    buffers: &[Vec<u8>],
    files: &dyn Files,
    m: &::gltf::Material,
    label: &str,
    textures: &mut TextureSet,
    notes: &mut BTreeSet<String>,
) -> Result<MaterialOut> {
    let p = path.display();
    let pbr = m.pbr_metallic_roughness();
    let base = pbr.base_color_factor();
    let strength = m.emissive_strength().unwrap_or(1.0);
    let emissive = m.emissive_factor().map(|e| e * strength);
    let transmission = m.transmission();
    let check = |what: &str, x: f32, range: std::ops::RangeInclusive<f32>| -> Result<f32> {
        if x.is_finite() && range.contains(&x) {
            Ok(x)
        } else {
            bail!("{p}: {label}: {what} {x} is outside {range:?}")
        }
    };
    for (i, c) in base.iter().enumerate() {
        check(&format!("baseColorFactor[{i}]"), *c, 0.0..=1.0)?;
    }
    for (i, c) in emissive.iter().enumerate() {
        check(&format!("emissiveFactor[{i}] × emissive strength"), *c, 0.0..=65504.0)?;
    }
    let pr = Principled {
        base_color: Vec3::new(base[0], base[1], base[2]),
        metallic: check("metallicFactor", pbr.metallic_factor(), 0.0..=1.0)?,
        roughness: check("roughnessFactor", pbr.roughness_factor(), 0.0..=1.0)?,
        transmission: check("transmission", transmission.as_ref().map_or(0.0, |t| t.transmission_factor()), 0.0..=1.0)?,
        ior: check("ior", m.ior().unwrap_or(1.5), 1.0..=10.0)?.max(1.0 + 1e-4),
    };
    let mut mat = principled(&pr, Vec3::from(emissive));
    // Textures: each slot's texture info with the kind it is read as.
    let bits = |v: [f32; 3]| v.map(f32::to_bits);
    let mut slots: Vec<(&str, ::gltf::texture::Info, usize, Kind)> = Vec::new();
    if let Some(t) = pbr.base_color_texture() {
        slots.push(("baseColorTexture", t, TEXTURE_ALBEDO, Kind::ColourTimes(bits([base[0], base[1], base[2]]))));
    }
    if let Some(t) = pbr.metallic_roughness_texture() {
        slots.push((
            "metallicRoughnessTexture",
            t.clone(),
            TEXTURE_ROUGHNESS,
            Kind::ChannelTimes(1, pr.roughness.to_bits()),
        ));
        slots.push(("metallicRoughnessTexture", t, TEXTURE_METALLIC, Kind::ChannelTimes(2, pr.metallic.to_bits())));
    }
    if let Some(t) = m.emissive_texture() {
        if emissive.iter().any(|e| *e > 0.0) {
            slots.push(("emissiveTexture", t, TEXTURE_EMISSION, Kind::ColourTimes(bits(emissive))));
        }
    }
    // Alpha: MASK cuts out where baseColor alpha × factor < cutoff; BLEND is stochastic
    // transparency with that alpha (`ALPHA_BLEND`), a constant one through a 1×1 texture.
    let mut invisible = false;
    let mut constant_alpha = None;
    let mode = m.alpha_mode();
    if mode == ::gltf::material::AlphaMode::Blend {
        mat.alpha_mode = ALPHA_BLEND;
        match pbr.base_color_texture() {
            Some(t) => {
                slots.push(("baseColorTexture (alpha)", t, TEXTURE_ALPHA, Kind::ChannelTimes(3, base[3].to_bits())));
            }
            None if base[3] < 1.0 => constant_alpha = Some(base[3]),
            None => {}
        }
    } else if mode == ::gltf::material::AlphaMode::Mask {
        let cutoff = m.alpha_cutoff().unwrap_or(0.5);
        if cutoff > 0.0 && cutoff.is_finite() {
            match pbr.base_color_texture() {
                Some(t) => {
                    // The mask reads alpha · factor · 0.5/cutoff against ALPHA_CUTOFF (0.5).
                    let scale = base[3] * ALPHA_CUTOFF / cutoff;
                    slots.push(("baseColorTexture (alpha)", t, TEXTURE_ALPHA, Kind::ChannelTimes(3, scale.to_bits())));
                }
                None => invisible = base[3] < cutoff,
            }
        }
    }
    let uv = slots.first().map_or(UvTransform::IDENTITY, |s| UvTransform::of(&s.1));
    for (key, info, slot, kind) in &slots {
        if UvTransform::of(info) != uv {
            notes.insert(format!(
                "{p}: {label}: {key} has a KHR_texture_transform of its own; all its textures use the {}'s",
                slots[0].0
            ));
        }
        let set = info.texture_transform().and_then(|t| t.tex_coord()).unwrap_or(info.tex_coord());
        if set != 0 {
            notes.insert(format!(
                "{p}: {label}: {key} reads TEXCOORD_{set}; kdtrace reads TEXCOORD_0 for every texture"
            ));
        }
        mat.textures[*slot] = load_texture(path, buffers, files, &info.texture(), label, key, *kind, textures, notes)?;
    }
    if let Some(alpha) = constant_alpha {
        let white = || {
            let mut png = Vec::new();
            image::RgbaImage::from_pixel(1, 1, image::Rgba([255; 4]))
                .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
                .map_err(|e| anyhow!("a 1×1 alpha texture: {e}"))?;
            Ok(png)
        };
        let wanted_by = format!("{p}: {label}: baseColorFactor alpha");
        let kind = Kind::ChannelTimes(3, alpha.to_bits());
        mat.textures[TEXTURE_ALPHA] =
            textures.load_bytes(Path::new("(constant alpha)"), white, kind, true, &wanted_by)?;
    }
    if mat.textures[TEXTURE_EMISSION] != NO_TEXTURE {
        let mean = textures.textures[mat.textures[TEXTURE_EMISSION] as usize - 1].mean_rgb();
        mat.emission = Vec3::from(mean).extend(0.0);
    }
    if let Some(n) = m.normal_texture() {
        let scale = n.scale();
        if !scale.is_finite() {
            bail!("{p}: {label}: normalTexture scale {scale} is not finite");
        }
        if n.tex_coord() != 0 {
            notes.insert(format!(
                "{p}: {label}: normalTexture reads TEXCOORD_{}; kdtrace reads TEXCOORD_0",
                n.tex_coord()
            ));
        }
        let texture = n.texture();
        use ::gltf::texture::WrappingMode as W;
        let clamp = texture.sampler().wrap_s() == W::ClampToEdge && texture.sampler().wrap_t() == W::ClampToEdge;
        let (name, bytes) = image_source(path, buffers, files, &texture.source());
        let wanted_by = format!("{p}: {label}: normalTexture");
        mat.textures[TEXTURE_NORMAL] = textures.load_bytes(&name, bytes, Kind::Linear, clamp, &wanted_by)?;
        mat.eta.w = scale;
    }
    if transmission.as_ref().is_some_and(|t| t.transmission_texture().is_some()) {
        notes.insert(format!("{p}: {label}: transmissionTexture ignored (the factor is used)"));
    }
    if let Some(coat) = m.extension_value("KHR_materials_clearcoat") {
        let factor = |key: &str| -> Result<f32> {
            match coat.get(key) {
                None => Ok(0.0),
                Some(v) => match v.as_f64() {
                    Some(x) => check(&format!("KHR_materials_clearcoat: {key}"), x as f32, 0.0..=1.0),
                    None => bail!("{p}: {label}: KHR_materials_clearcoat: {key} is not a number: {v}"),
                },
            }
        };
        let strength = factor("clearcoatFactor")?;
        mat = clearcoat(mat, strength, factor("clearcoatRoughnessFactor")?);
        // clearcoatTexture's R channel scales the factor (at TEXCOORD_0, with the material's
        // texture transform: kdtrace has one set of coordinates per triangle).
        if let Some(info) = coat.get("clearcoatTexture") {
            let key = "KHR_materials_clearcoat: clearcoatTexture";
            let index = info.get("index").and_then(|i| i.as_u64());
            let texture = index.and_then(|i| document.textures().nth(i as usize));
            let Some(texture) = texture else {
                bail!("{p}: {label}: {key}: no texture {:?} in the file", info.get("index"));
            };
            if info.get("texCoord").and_then(|c| c.as_u64()).is_some_and(|c| c != 0) {
                notes.insert(format!("{p}: {label}: {key} reads another TEXCOORD; kdtrace reads TEXCOORD_0"));
            }
            let kind = Kind::ChannelTimes(0, strength.to_bits());
            mat.textures[TEXTURE_CLEARCOAT] =
                load_texture(path, buffers, files, &texture, label, key, kind, textures, notes)?;
        }
        for key in ["clearcoatRoughnessTexture", "clearcoatNormalTexture"] {
            if coat.get(key).is_some() {
                notes.insert(format!("{p}: {label}: KHR_materials_clearcoat: {key} ignored (the factor is used)"));
            }
        }
    }
    if let Some(volume) = m.volume() {
        mat.k = absorption(volume.attenuation_color(), volume.attenuation_distance()).extend(0.0);
        if volume.thickness_texture().is_some() {
            notes.insert(format!(
                "{p}: {label}: KHR_materials_volume: thicknessTexture ignored (rays measure the mesh)"
            ));
        }
    }
    Ok(MaterialOut { material: mat, uv, invisible })
}

/// Loads `texture` for material `label`'s `key`, read as `kind`; returns its slot value. A wrap
/// mode kdtrace does not have is noted.
#[allow(clippy::too_many_arguments)]
fn load_texture(
    path: &Path,
    buffers: &[Vec<u8>],
    files: &dyn Files,
    texture: &::gltf::Texture,
    label: &str,
    key: &str,
    kind: Kind,
    textures: &mut TextureSet,
    notes: &mut BTreeSet<String>,
) -> Result<u32> {
    let p = path.display();
    let sampler = texture.sampler();
    use ::gltf::texture::WrappingMode as W;
    let (s, t) = (sampler.wrap_s(), sampler.wrap_t());
    let clamp = s == W::ClampToEdge && t == W::ClampToEdge;
    if !clamp && (s != W::Repeat || t != W::Repeat) {
        notes.insert(format!(
            "{p}: {label}: {key}: sampler wrapping {s:?}/{t:?} is rendered as Repeat (kdtrace wraps both axes alike, \
             repeat or clamp)"
        ));
    }
    let (name, bytes) = image_source(path, buffers, files, &texture.source());
    let wanted_by = format!("{p}: {label}: {key}");
    textures.load_bytes(&name, bytes, kind, clamp, &wanted_by)
}

/// KHR_materials_volume's absorption coefficient per unit length: light that travels
/// `distance` inside keeps `color` (Beer–Lambert: σ = −ln(color)/distance per channel; an
/// infinite distance, the default, absorbs nothing). A colour of 0 is taken as 1e-30 so that σ
/// stays finite.
pub fn absorption(color: [f32; 3], distance: f32) -> Vec3 {
    if !(distance.is_finite() && distance > 0.0) {
        return Vec3::ZERO;
    }
    Vec3::from(color.map(|c| (-(c.clamp(1e-30, 1.0) as f64).ln() / distance as f64) as f32))
}
