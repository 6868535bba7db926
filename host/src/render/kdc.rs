//! The compiled scene file (`.kdc`): triangles, per-triangle info, materials, lights and the
//! built k-d tree in one versioned, checksummed binary file that loads without parsing or
//! building anything.
//!
//! Layout (all integers little-endian):
//!
//! | offset | size | what |
//! |---|---|---|
//! | 0 | 8 | magic `\x89KDC\r\n\x1a\n` (PNG's trick: catches text-mode and truncating transfers) |
//! | 8 | 4 | format version ([`FORMAT_VERSION`]) |
//! | 12 | 4 | JSON header length in bytes, a multiple of 16 (space-padded) |
//! | 16 | 8 | payload length: everything after these 32 bytes |
//! | 24 | 8 | XXH3-64 of every other byte of the file (bytes 0..24, then 32..) |
//! | 32 | … | JSON header: writer, build settings (serde), scene settings, material names, bounds, the environment map's size, strength and rotation, the punctual lights, counts |
//! | … | … | sections of packed `shared::layout` structs: triangles, triangle info, materials, lights, nodes, indices, vertex attributes (none, or one per triangle), the texture buffer (`shared::texture`), the environment map's texels (RGB f32, none without a map) |
//!
//! Reading trusts nothing: the version is checked before anything else, every section size is
//! derived from the header's counts with checked arithmetic and must add up to the file's actual
//! length before anything is allocated, the checksum must match, and every index the renderers
//! follow (node children, leaf ranges, triangle, material and light ids) is validated, so a
//! crafted file can neither make the reader allocate absurd sizes nor make a renderer panic or
//! read out of bounds. Validation only reads and is safe on any bytes, so it runs beside the
//! checksum (rayon::join); a checksum mismatch is still what gets reported first.
use crate::files;
use crate::kdbuild::{check_structure, BuildSettings, KdTree};
use crate::render::Compiled;
use crate::scene::obj::MAX_COORDINATE;
use crate::scene::{EnvironmentMap, PunctualLight, Scene};
use crate::settings::scene::SceneSettings;
use anyhow::{anyhow, bail, Context, Result};
use bytemuck::Pod;
use serde::{Deserialize, Serialize};
use shared::glam::{DVec3, Vec3, Vec4};
use shared::layout::{
    KdNode, Light, Material, Triangle, TriangleAttributes, TriangleInfo, ALPHA_BLEND, ALPHA_CUT, KD_MAX_DEPTH,
    MATERIAL_CONDUCTOR, MATERIAL_DIELECTRIC, MATERIAL_DIFFUSE, MATERIAL_PLASTIC, MATERIAL_PRINCIPLED, NO_LIGHT,
    PUNCTUAL_DIRECTIONAL, PUNCTUAL_POINT, PUNCTUAL_SPOT,
};
use std::path::Path;
use xxhash_rust::xxh3::Xxh3;

pub const MAGIC: [u8; 8] = *b"\x89KDC\r\n\x1a\n";
/// Bump on any change of the layout or of the meaning of a field.
pub const FORMAT_VERSION: u32 = 4;
/// Bytes before the JSON header.
pub const FIXED_HEADER: usize = 32;

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Counts {
    triangles: u64,
    materials: u64,
    lights: u64,
    nodes: u64,
    indices: u64,
    /// Vertex attributes: 0 or `triangles`.
    attributes: u64,
    /// Textures in the table, and words of the texture buffer (table and texels).
    textures: u64,
    texture_words: u64,
    /// The environment map's texels (width × height), 0 without one.
    environment_texels: u64,
}

/// An environment map in the header; its texels are a section.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct EnvironmentHeader {
    width: u32,
    height: u32,
    strength: f32,
    rotate: [f64; 3],
    source: String,
}

/// A punctual light in the header (`scene::PunctualLight`; position in the scene's local frame).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct LightHeader {
    kind: u32,
    position: [f64; 3],
    direction: [f64; 3],
    color: [f32; 3],
    intensity: f32,
    inner_cone_angle: f32,
    outer_cone_angle: f32,
}

impl LightHeader {
    fn of(l: &PunctualLight) -> Self {
        Self {
            kind: l.kind,
            position: l.position.to_array(),
            direction: l.direction.to_array(),
            color: l.color.to_array(),
            intensity: l.intensity,
            inner_cone_angle: l.inner_cone_angle,
            outer_cone_angle: l.outer_cone_angle,
        }
    }

    /// The light, checked as a scene file's would be.
    fn light(&self, i: usize) -> Result<PunctualLight> {
        if ![PUNCTUAL_POINT, PUNCTUAL_SPOT, PUNCTUAL_DIRECTIONAL].contains(&self.kind) {
            bail!("punctual light {i}: unknown kind {}", self.kind);
        }
        let l = PunctualLight {
            kind: self.kind,
            position: DVec3::from(self.position),
            direction: DVec3::from(self.direction),
            color: Vec3::from(self.color),
            intensity: self.intensity,
            inner_cone_angle: self.inner_cone_angle,
            outer_cone_angle: self.outer_cone_angle,
        };
        l.check().with_context(|| format!("punctual light {i}"))?;
        Ok(l)
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Header {
    /// `kdtrace <version>` of the writer, for messages.
    writer: String,
    build_settings: BuildSettings,
    settings: SceneSettings,
    material_names: Vec<String>,
    /// The image file of each texture, for messages.
    texture_sources: Vec<String>,
    dropped_degenerate: usize,
    scene_bounds: [[f32; 3]; 2],
    tree_bounds: [[f32; 3]; 2],
    tree_depth: u32,
    /// World position of the scene's origin (`local_frame`), f64; absent in files from before it.
    #[serde(default)]
    origin: [f64; 3],
    environment: Option<EnvironmentHeader>,
    punctual_lights: Vec<LightHeader>,
    counts: Counts,
}

/// A compiled scene as read back.
pub struct KdcScene {
    pub compiled: Compiled,
    pub build_settings: BuildSettings,
    pub settings: SceneSettings,
    /// `kdtrace <version>` that wrote it.
    pub writer: String,
}

fn writer() -> String {
    format!("kdtrace {}", env!("CARGO_PKG_VERSION"))
}

/// The bytes of a `.kdc` file.
pub fn encode(c: &Compiled, build_settings: &BuildSettings, settings: &SceneSettings) -> Result<Vec<u8>> {
    let (s, t) = (&c.scene, c.tree());
    let map = s.environment_map.as_ref();
    let header = Header {
        writer: writer(),
        build_settings: *build_settings,
        settings: settings.clone(),
        material_names: s.material_names.clone(),
        texture_sources: s.texture_sources.clone(),
        dropped_degenerate: s.dropped_degenerate,
        scene_bounds: [s.bounds_min.to_array(), s.bounds_max.to_array()],
        tree_bounds: [t.bounds_min.to_array(), t.bounds_max.to_array()],
        tree_depth: t.depth,
        origin: c.origin.to_array(),
        environment: map.map(|m| EnvironmentHeader {
            width: m.width,
            height: m.height,
            strength: m.strength,
            rotate: m.rotate,
            source: m.source.clone(),
        }),
        punctual_lights: s.punctual_lights.iter().map(LightHeader::of).collect(),
        counts: Counts {
            triangles: s.triangles.len() as u64,
            materials: s.materials.len() as u64,
            lights: s.lights.len() as u64,
            nodes: t.nodes.len() as u64,
            indices: t.indices.len() as u64,
            attributes: s.attributes.len() as u64,
            textures: s.texture_sources.len() as u64,
            texture_words: s.textures.len() as u64,
            environment_texels: map.map_or(0, |m| m.texels.len() as u64),
        },
    };
    let mut json = serde_json::to_vec(&header).context("encoding the .kdc header")?;
    // Pad so that every section starts 16-byte aligned (Triangle and Material hold Vec4s).
    json.resize(json.len().next_multiple_of(16), b' ');
    let sections: [&[u8]; 9] = [
        bytemuck::cast_slice(&s.triangles),
        bytemuck::cast_slice(&s.info),
        bytemuck::cast_slice(&s.materials),
        bytemuck::cast_slice(&s.lights),
        bytemuck::cast_slice(&t.nodes),
        bytemuck::cast_slice(&t.indices),
        bytemuck::cast_slice(&s.attributes),
        bytemuck::cast_slice(&s.textures),
        map.map_or(&[][..], |m| bytemuck::cast_slice(&m.texels)),
    ];
    let payload = json.len() + sections.iter().map(|b| b.len()).sum::<usize>();
    let mut out = Vec::with_capacity(FIXED_HEADER + payload);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&u32::try_from(json.len()).context("header too long")?.to_le_bytes());
    out.extend_from_slice(&(payload as u64).to_le_bytes());
    out.extend_from_slice(&0u64.to_le_bytes());
    out.extend_from_slice(&json);
    for b in sections {
        out.extend_from_slice(b);
    }
    seal(&mut out);
    Ok(out)
}

/// Writes the file through a temporary file and a rename (`files::write_atomic`): a failure
/// never leaves half a file under the real name, and leaves a previous file as it was.
pub fn write(path: &Path, c: &Compiled, build_settings: &BuildSettings, settings: &SceneSettings) -> Result<()> {
    files::write_bytes(path, &encode(c, build_settings, settings)?)
}

/// Stores the payload's checksum in its slot (for writers, and for tests and fuzzers that craft
/// files to reach the validation behind the checksum). Does nothing to a too-short buffer.
pub fn seal(bytes: &mut [u8]) {
    if bytes.len() >= FIXED_HEADER {
        let sum = checksum(bytes);
        bytes[24..32].copy_from_slice(&sum.to_le_bytes());
    }
}

/// XXH3-64 of the file without its checksum slot (bytes 24..32). `bytes` holds at least the
/// fixed header.
fn checksum(bytes: &[u8]) -> u64 {
    let mut h = Xxh3::new();
    h.update(&bytes[..24]);
    h.update(&bytes[FIXED_HEADER..]);
    h.digest()
}

/// Reads a `.kdc` file. Each section is read straight into its final, typed buffer (one copy
/// from the page cache, no file-sized intermediate buffer).
pub fn read(path: &Path) -> Result<KdcScene> {
    let cannot = |e: std::io::Error| anyhow!("{}: cannot read: {e}", path.display());
    // A regular file within the cap, checked before it is opened (a FIFO would block).
    files::input_size(path, files::MAX_KDC_BYTES).map_err(cannot)?;
    let file = std::fs::File::open(path).map_err(cannot)?;
    let len = file.metadata().map_err(cannot)?.len();
    decode_from(path, &file, len)
}

/// Decodes and validates a `.kdc` file's bytes; `path` only names it in messages.
pub fn decode(path: &Path, bytes: &[u8]) -> Result<KdcScene> {
    decode_from(path, &bytes, bytes.len() as u64)
}

/// Input read at given offsets (a file or bytes in memory).
pub trait ReadAt: Sync {
    fn read_exact_at(&self, buf: &mut [u8], offset: u64) -> std::io::Result<()>;
}

impl ReadAt for &[u8] {
    fn read_exact_at(&self, buf: &mut [u8], offset: u64) -> std::io::Result<()> {
        let start = usize::try_from(offset).unwrap_or(usize::MAX);
        let src = start.checked_add(buf.len()).and_then(|end| self.get(start..end));
        let src = src.ok_or_else(|| std::io::Error::from(std::io::ErrorKind::UnexpectedEof))?;
        buf.copy_from_slice(src);
        Ok(())
    }
}

#[cfg(unix)]
impl ReadAt for std::fs::File {
    fn read_exact_at(&self, buf: &mut [u8], offset: u64) -> std::io::Result<()> {
        std::os::unix::fs::FileExt::read_exact_at(self, buf, offset)
    }
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap_or_default())
}

fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().unwrap_or_default())
}

/// Decodes a `.kdc` file of `len` bytes from `input`; `path` only names it in messages.
pub fn decode_from(path: &Path, input: &dyn ReadAt, len: u64) -> Result<KdcScene> {
    let name = path.display();
    if cfg!(target_endian = "big") {
        bail!("{name}: .kdc files are little-endian; this machine is big-endian");
    }
    let io = |e: std::io::Error| anyhow!("{name}: cannot read: {e}");
    let mut fixed = vec![0u8; len.min(FIXED_HEADER as u64) as usize];
    input.read_exact_at(&mut fixed, 0).map_err(io)?;
    let head = &fixed[..fixed.len().min(MAGIC.len())];
    if head != &MAGIC[..head.len()] {
        bail!("{name}: not a kdtrace compiled scene (no .kdc magic number)");
    }
    if fixed.len() < FIXED_HEADER {
        bail!("{name}: truncated: {len} bytes, shorter than the {FIXED_HEADER}-byte .kdc header");
    }
    let version = u32_at(&fixed, 8);
    if version != FORMAT_VERSION {
        bail!(
            "{name}: .kdc format version {version}, but this kdtrace reads version {FORMAT_VERSION}: compile the \
             scene again with `kdtrace compile`"
        );
    }
    let header_len = u32_at(&fixed, 12) as u64;
    let payload_len = u64_at(&fixed, 16);
    let actual = len - FIXED_HEADER as u64;
    if payload_len > actual {
        bail!("{name}: truncated: {len} bytes, the header says {}", payload_len.saturating_add(FIXED_HEADER as u64));
    }
    if payload_len < actual {
        bail!(
            "{name}: {} bytes after the end the header states ({} bytes)",
            actual - payload_len,
            payload_len + FIXED_HEADER as u64
        );
    }
    if header_len > payload_len {
        bail!("{name}: header length {header_len} beyond the payload ({payload_len} bytes)");
    }
    // Every length below is now bounded by the file's.
    let mut json = vec![0u8; header_len as usize];
    input.read_exact_at(&mut json, FIXED_HEADER as u64).map_err(io)?;
    let body_at = FIXED_HEADER as u64 + header_len;
    let body_len = payload_len - header_len;
    let mut hasher = Xxh3::new();
    hasher.update(&fixed[..24]);
    hasher.update(&json);
    let stored = u64_at(&fixed, 24);
    let mismatch = |computed: u64| {
        anyhow!("{name}: checksum mismatch (stored {stored:016x}, computed {computed:016x}): the file is corrupted")
    };
    // The header is read before the checksum is known to match (the section counts are in it),
    // but nothing it says is trusted until the checksum has matched.
    let header: Option<Header> = serde_json::from_slice(&json).ok();
    let sections = match &header {
        Some(h) if section_bytes(&h.counts) == Some(body_len) => {
            Some(Sections::read(&h.counts, input, body_at).map_err(io)?)
        }
        _ => None,
    };
    let Some(sections) = sections else {
        hash_range(input, body_at, body_len, &mut hasher).map_err(io)?;
        if hasher.digest() != stored {
            return Err(mismatch(hasher.digest()));
        }
        let header: Header = serde_json::from_slice(&json).map_err(|e| anyhow!("{name}: header: {e}"))?;
        return Err(counts_error(&header.counts, body_len))
            .with_context(|| format!("{name}: invalid compiled scene (written by {})", header.writer));
    };
    let header = header.unwrap_or_else(|| unreachable!("sections are only read with a header"));
    // Validation only reads, and is safe on any bytes, so it runs beside the checksum; a
    // mismatch is reported first.
    let (computed, valid) = rayon::join(
        || {
            sections.hash_into(&mut hasher);
            hasher.digest()
        },
        || validate(&header, &sections),
    );
    if computed != stored {
        return Err(mismatch(computed));
    }
    let invalid = || format!("{name}: invalid compiled scene (written by {})", header.writer);
    valid.with_context(invalid)?;
    let lights = header.punctual_lights.iter().enumerate().map(|(i, l)| l.light(i)).collect::<Result<Vec<_>>>();
    let lights = lights.with_context(invalid)?;
    let mut sections = sections;
    let texels = std::mem::take(&mut sections.environment);
    let mut compiled = sections.into_compiled(&header);
    compiled.scene.environment_map = compiled_map(&header, texels).with_context(invalid)?;
    compiled.scene.punctual_lights = lights;
    compiled.prepare_emitters();
    Ok(KdcScene { compiled, build_settings: header.build_settings, settings: header.settings, writer: header.writer })
}

/// Hashes `len` bytes from `at` in bounded chunks (the sections are not read for a header that
/// does not describe them).
fn hash_range(input: &dyn ReadAt, at: u64, len: u64, hasher: &mut Xxh3) -> std::io::Result<()> {
    let mut chunk = vec![0u8; len.min(1 << 20) as usize];
    let mut done = 0u64;
    while done < len {
        let n = (len - done).min(chunk.len() as u64) as usize;
        input.read_exact_at(&mut chunk[..n], at + done)?;
        hasher.update(&chunk[..n]);
        done += n as u64;
    }
    Ok(())
}

/// (what, count, element size) of each section in file order.
fn section_sizes(c: &Counts) -> [(&'static str, u64, usize); 9] {
    [
        ("triangles", c.triangles, size_of::<Triangle>()),
        ("triangle info", c.triangles, size_of::<TriangleInfo>()),
        ("materials", c.materials, size_of::<Material>()),
        ("lights", c.lights, size_of::<Light>()),
        ("nodes", c.nodes, size_of::<KdNode>()),
        ("indices", c.indices, size_of::<u32>()),
        ("vertex attributes", c.attributes, size_of::<TriangleAttributes>()),
        ("textures", c.texture_words, size_of::<u32>()),
        ("environment texels", c.environment_texels, size_of::<[f32; 3]>()),
    ]
}

/// The environment map the header describes with its texels' section (checked as a map file's
/// are).
fn compiled_map(h: &Header, texels: Vec<[f32; 3]>) -> Result<Option<EnvironmentMap>> {
    match &h.environment {
        None if texels.is_empty() => Ok(None),
        None => bail!("{} environment texels without an environment map", texels.len()),
        Some(e) => {
            if e.width as u64 * e.height as u64 != texels.len() as u64 {
                bail!("environment map {}×{} with {} texels", e.width, e.height, texels.len());
            }
            EnvironmentMap::new(e.width, e.height, texels, e.strength, e.rotate, e.source.clone()).map(Some)
        }
    }
}

/// The bytes the sections take, or `None` when that overflows.
fn section_bytes(c: &Counts) -> Option<u64> {
    section_sizes(c)
        .iter()
        .try_fold(0u64, |total, &(_, count, size)| total.checked_add(count.checked_mul(size as u64)?))
}

fn counts_error(c: &Counts, available: u64) -> anyhow::Error {
    for (what, count, size) in section_sizes(c) {
        if count.checked_mul(size as u64).is_none() {
            return anyhow!("{what}: count {count} overflows");
        }
    }
    match section_bytes(c) {
        Some(total) => anyhow!("the header's counts need {total} bytes of sections, the file holds {available}"),
        None => anyhow!("section sizes overflow"),
    }
}

/// The sections as read, not yet validated.
struct Sections {
    triangles: Vec<Triangle>,
    info: Vec<TriangleInfo>,
    materials: Vec<Material>,
    lights: Vec<Light>,
    nodes: Vec<KdNode>,
    indices: Vec<u32>,
    attributes: Vec<TriangleAttributes>,
    textures: Vec<u32>,
    environment: Vec<[f32; 3]>,
}

impl Sections {
    /// Reads each section into its buffer, in file order; `c` must already be known to fit the
    /// file. (Reading two sections on two threads was measured slower: page faults contend.)
    fn read(c: &Counts, input: &dyn ReadAt, at: u64) -> std::io::Result<Self> {
        let tri_bytes = c.triangles * size_of::<Triangle>() as u64;
        let (triangles, rest) = (
            section::<Triangle>(c.triangles, input, at),
            (|| -> std::io::Result<_> {
                let mut at = at + tri_bytes;
                let mut next = |count: u64, size: usize| {
                    let here = at;
                    at += count * size as u64;
                    here
                };
                let info = section::<TriangleInfo>(c.triangles, input, next(c.triangles, size_of::<TriangleInfo>()))?;
                let materials = section::<Material>(c.materials, input, next(c.materials, size_of::<Material>()))?;
                let lights = section::<Light>(c.lights, input, next(c.lights, size_of::<Light>()))?;
                let nodes = section::<KdNode>(c.nodes, input, next(c.nodes, size_of::<KdNode>()))?;
                let indices = section::<u32>(c.indices, input, next(c.indices, size_of::<u32>()))?;
                let attributes = section::<TriangleAttributes>(
                    c.attributes,
                    input,
                    next(c.attributes, size_of::<TriangleAttributes>()),
                )?;
                let textures = section::<u32>(c.texture_words, input, next(c.texture_words, size_of::<u32>()))?;
                let environment = section::<[f32; 3]>(
                    c.environment_texels,
                    input,
                    next(c.environment_texels, size_of::<[f32; 3]>()),
                )?;
                Ok((info, materials, lights, nodes, indices, attributes, textures, environment))
            })(),
        );
        let (info, materials, lights, nodes, indices, attributes, textures, environment) = rest?;
        Ok(Sections {
            triangles: triangles?,
            info,
            materials,
            lights,
            nodes,
            indices,
            attributes,
            textures,
            environment,
        })
    }

    /// Feeds the sections to the checksum in file order.
    fn hash_into(&self, h: &mut Xxh3) {
        h.update(bytemuck::cast_slice(&self.triangles));
        h.update(bytemuck::cast_slice(&self.info));
        h.update(bytemuck::cast_slice(&self.materials));
        h.update(bytemuck::cast_slice(&self.lights));
        h.update(bytemuck::cast_slice(&self.nodes));
        h.update(bytemuck::cast_slice(&self.indices));
        h.update(bytemuck::cast_slice(&self.attributes));
        h.update(bytemuck::cast_slice(&self.textures));
        h.update(bytemuck::cast_slice(&self.environment));
    }

    fn into_compiled(self, h: &Header) -> Compiled {
        let [lo, hi] = h.scene_bounds;
        let [tree_lo, tree_hi] = h.tree_bounds;
        let tree = KdTree {
            nodes: self.nodes,
            indices: self.indices,
            bounds_min: Vec3::from(tree_lo),
            bounds_max: Vec3::from(tree_hi),
            depth: h.tree_depth,
        };
        let scene = Scene {
            triangles: self.triangles,
            info: self.info,
            materials: self.materials,
            material_names: h.material_names.clone(),
            lights: self.lights,
            bounds_min: Vec3::from(lo),
            bounds_max: Vec3::from(hi),
            dropped_degenerate: h.dropped_degenerate,
            attributes: self.attributes,
            textures: self.textures,
            texture_sources: h.texture_sources.clone(),
            environment_map: None,
            punctual_lights: Vec::new(),
        };
        Compiled { origin: DVec3::from(h.origin), ..Compiled::new(scene, tree) }
    }
}

/// `count` elements read straight into a zero-allocated (lazily mapped) buffer.
fn section<T: Pod>(count: u64, input: &dyn ReadAt, at: u64) -> std::io::Result<Vec<T>> {
    let mut v: Vec<T> = bytemuck::zeroed_vec(count as usize);
    input.read_exact_at(bytemuck::cast_slice_mut(&mut v), at)?;
    Ok(v)
}

/// Checks everything the renderers rely on: the tree on one thread, the rest on another.
fn validate(h: &Header, s: &Sections) -> Result<()> {
    let bounds = |b: [[f32; 3]; 2], what: &str| -> Result<(Vec3, Vec3)> {
        let (lo, hi) = (Vec3::from(b[0]), Vec3::from(b[1]));
        if !lo.is_finite() || !hi.is_finite() || lo.cmpgt(hi).any() {
            bail!("{what} bounds {lo}..{hi} are not a finite box");
        }
        Ok((lo, hi))
    };
    bounds(h.scene_bounds, "scene")?;
    if !DVec3::from(h.origin).is_finite() {
        bail!("scene origin {:?} is not finite", h.origin);
    }
    let (tree_lo, tree_hi) = bounds(h.tree_bounds, "tree")?;
    let (tree, rest) = rayon::join(
        || check_tree(&s.nodes, &s.indices, s.triangles.len(), tree_lo, tree_hi, h.tree_depth),
        || check_scene(h, s),
    );
    rest.and(tree)
}

/// Counts, vertices, materials, per-triangle ids and the light table.
fn check_scene(h: &Header, s: &Sections) -> Result<()> {
    let Sections { triangles, info, materials, lights, attributes, textures, .. } = s;
    if triangles.len() >= 1 << 30 || lights.len() >= u32::MAX as usize || materials.len() >= u32::MAX as usize {
        bail!("too many triangles, lights or materials");
    }
    if h.material_names.len() != materials.len() {
        bail!("{} material names for {} materials", h.material_names.len(), materials.len());
    }
    let texture_count = h.counts.textures;
    if h.texture_sources.len() as u64 != texture_count {
        bail!("{} texture names for {texture_count} textures", h.texture_sources.len());
    }
    crate::scene::texture::check_packed(textures, texture_count as usize).map_err(|e| anyhow!("textures: {e}"))?;
    if !attributes.is_empty() && attributes.len() != triangles.len() {
        bail!("{} vertex attributes for {} triangles", attributes.len(), triangles.len());
    }
    for (i, a) in attributes.iter().enumerate() {
        if ![a.n0, a.n1, a.n2, a.uv_v].iter().all(|v| v.is_finite()) {
            bail!("triangle {i}: vertex attributes not finite");
        }
    }
    for (i, t) in triangles.iter().enumerate() {
        for v in [t.v0, t.v1, t.v2] {
            if !v.is_finite() || v.abs().max_element() > MAX_COORDINATE {
                bail!("triangle {i}: vertex {v} not finite or beyond ±{MAX_COORDINATE:e}");
            }
        }
    }
    let rgb_ok = |v: Vec4| v.truncate().is_finite() && v.truncate().min_element() >= 0.0;
    for (i, m) in materials.iter().enumerate() {
        if ![MATERIAL_DIFFUSE, MATERIAL_CONDUCTOR, MATERIAL_DIELECTRIC, MATERIAL_PLASTIC, MATERIAL_PRINCIPLED]
            .contains(&m.kind)
        {
            bail!("material {i}: unknown kind {}", m.kind);
        }
        if ![ALPHA_CUT, ALPHA_BLEND].contains(&m.alpha_mode) {
            bail!("material {i}: unknown alpha mode {}", m.alpha_mode);
        }
        if !rgb_ok(m.albedo) || !rgb_ok(m.emission) || !rgb_ok(m.eta) || !rgb_ok(m.k) || !m.params.is_finite() {
            bail!("material {i}: colours and indices of refraction must be finite and non-negative");
        }
        if let Some(t) = m.textures.iter().find(|&&t| t as u64 > texture_count) {
            bail!("material {i}: texture {t} out of range ({texture_count} textures)");
        }
        if !(0.0..=1.0).contains(&m.params.x) {
            bail!("material {i}: roughness alpha {} must be within 0..=1", m.params.x);
        }
        if m.kind == MATERIAL_PRINCIPLED && !(0.0..=1.0).contains(&m.params.z) | !(0.0..=1.0).contains(&m.params.w) {
            bail!("material {i}: metallic {} and transmission {} must be within 0..=1", m.params.z, m.params.w);
        }
        if m.kind == MATERIAL_PRINCIPLED && !(0.0..=1.0).contains(&m.eta.x) | !(0.0..=1.0).contains(&m.eta.y) {
            bail!("material {i}: clear coat {} and its roughness alpha {} must be within 0..=1", m.eta.x, m.eta.y);
        }
        // A rough plastic's coating table travels in the texture section, after the textures.
        let table_end = m.table as u64 + shared::material::ROUGH_PLASTIC_TABLE_WORDS as u64;
        if m.kind == MATERIAL_PLASTIC && m.params.x > 0.0 && table_end > textures.len() as u64 {
            bail!("material {i}: coating table at word {} beyond the texture section", m.table);
        }
        let refracts = [MATERIAL_DIELECTRIC, MATERIAL_PLASTIC, MATERIAL_PRINCIPLED].contains(&m.kind);
        if refracts && !(m.params.y > 0.0) {
            bail!("material {i}: index of refraction {} must be positive", m.params.y);
        }
    }
    for (i, t) in info.iter().enumerate() {
        if t.material as usize >= materials.len() {
            bail!("triangle {i}: material {} out of range ({} materials)", t.material, materials.len());
        }
        if t.light != NO_LIGHT && lights.get(t.light as usize).map(|l| l.triangle) != Some(i as u32) {
            bail!("triangle {i}: light {} out of range or not pointing back to it", t.light);
        }
    }
    let mut previous_cdf = 0.0f32;
    for (i, l) in lights.iter().enumerate() {
        if info.get(l.triangle as usize).map(|t| t.light) != Some(i as u32) {
            bail!("light {i}: triangle {} out of range or not pointing back to it", l.triangle);
        }
        if !(l.pmf.is_finite()
            && l.pmf >= 0.0
            && l.area.is_finite()
            && l.area > 0.0
            && l.cdf.is_finite()
            && l.cdf >= previous_cdf
            && l.cdf <= 1.0)
        {
            bail!("light {i}: pmf {}, cdf {}, area {} not a valid distribution entry", l.pmf, l.cdf, l.area);
        }
        previous_cdf = l.cdf;
    }
    Ok(())
}

/// The tree's structure (`kdbuild::check_structure`, shared with `kdtrace tree --validate`), its
/// stated depth and its bounds. Split positions are not checked against their node's box
/// (`kdbuild::validate` does that and triangle placement, far slower, and neither matters for
/// memory safety).
fn check_tree(nodes: &[KdNode], indices: &[u32], triangles: usize, lo: Vec3, hi: Vec3, depth: u32) -> Result<()> {
    if depth > KD_MAX_DEPTH {
        bail!("k-d tree depth {depth} beyond {KD_MAX_DEPTH}");
    }
    if !lo.is_finite() || !hi.is_finite() {
        bail!("k-d tree bounds not finite");
    }
    let reached = check_structure(nodes, indices, triangles).map_err(|e| anyhow!("k-d tree: {e}"))?;
    if reached > depth {
        bail!("k-d tree reaches depth {reached}, beyond the {depth} its header states");
    }
    Ok(())
}
