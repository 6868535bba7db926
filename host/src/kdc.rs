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
//! | 32 | … | JSON header: writer, build settings (serde, never listed by hand), scene settings, material names, bounds, section counts |
//! | … | … | sections, each a packed array of the `shared::layout` struct: triangles, triangle info, materials, lights, k-d nodes, triangle indices |
//!
//! Reading trusts nothing: the version is checked before anything else, every section size is
//! derived from the header's counts with checked arithmetic and must add up to the file's actual
//! length before anything is allocated, the checksum must match, and every index the renderers
//! follow (node children, leaf ranges, triangle, material and light ids) is validated, so a
//! crafted file can neither make the reader allocate absurd sizes nor make a renderer panic or
//! read out of bounds.
use crate::kdbuild::{BuildSettings, KdTree};
use crate::obj::MAX_COORDINATE;
use crate::render::Compiled;
use crate::scene::Scene;
use crate::scene_settings::SceneSettings;
use anyhow::{anyhow, bail, Context, Result};
use bytemuck::Pod;
use serde::{Deserialize, Serialize};
use shared::glam::{Vec3, Vec4};
use shared::layout::{KdNode, Light, Material, Triangle, TriangleInfo, KD_MAX_DEPTH, MATERIAL_DIFFUSE, NO_LIGHT};
use std::path::Path;
use xxhash_rust::xxh3::Xxh3;

pub const MAGIC: [u8; 8] = *b"\x89KDC\r\n\x1a\n";
/// Bump on any change of the layout or of the meaning of a field.
pub const FORMAT_VERSION: u32 = 1;
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
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Header {
    /// `kdtrace <version>` of the writer, for messages.
    writer: String,
    build_settings: BuildSettings,
    settings: SceneSettings,
    material_names: Vec<String>,
    dropped_degenerate: usize,
    scene_bounds: [[f32; 3]; 2],
    tree_bounds: [[f32; 3]; 2],
    tree_depth: u32,
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
    let (s, t) = (&c.scene, &c.tree);
    let header = Header {
        writer: writer(),
        build_settings: *build_settings,
        settings: settings.clone(),
        material_names: s.material_names.clone(),
        dropped_degenerate: s.dropped_degenerate,
        scene_bounds: [s.bounds_min.to_array(), s.bounds_max.to_array()],
        tree_bounds: [t.bounds_min.to_array(), t.bounds_max.to_array()],
        tree_depth: t.depth,
        counts: Counts {
            triangles: s.triangles.len() as u64,
            materials: s.materials.len() as u64,
            lights: s.lights.len() as u64,
            nodes: t.nodes.len() as u64,
            indices: t.indices.len() as u64,
        },
    };
    let mut json = serde_json::to_vec(&header).context("encoding the .kdc header")?;
    // Pad so that every section starts 16-byte aligned (Triangle and Material hold Vec4s).
    json.resize(json.len().next_multiple_of(16), b' ');
    let sections: [&[u8]; 6] = [
        bytemuck::cast_slice(&s.triangles),
        bytemuck::cast_slice(&s.info),
        bytemuck::cast_slice(&s.materials),
        bytemuck::cast_slice(&s.lights),
        bytemuck::cast_slice(&t.nodes),
        bytemuck::cast_slice(&t.indices),
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

/// Writes the file through a temporary name and a rename, so a crash never leaves half a file
/// under the real name.
pub fn write(path: &Path, c: &Compiled, build_settings: &BuildSettings, settings: &SceneSettings) -> Result<()> {
    let bytes = encode(c, build_settings, settings)?;
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".partial");
    std::fs::write(&tmp, &bytes).with_context(|| format!("{}: cannot write", path.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("{}: cannot write", path.display()))
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

pub fn read(path: &Path) -> Result<KdcScene> {
    let bytes = std::fs::read(path).map_err(|e| anyhow!("{}: cannot read: {e}", path.display()))?;
    decode(path, &bytes)
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap_or_default())
}

fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().unwrap_or_default())
}

/// Decodes and validates a `.kdc` file's bytes; `path` only names it in messages.
pub fn decode(path: &Path, bytes: &[u8]) -> Result<KdcScene> {
    let name = path.display();
    if cfg!(target_endian = "big") {
        bail!("{name}: .kdc files are little-endian; this machine is big-endian");
    }
    let head = &bytes[..bytes.len().min(MAGIC.len())];
    if head != &MAGIC[..head.len()] {
        bail!("{name}: not a kdtrace compiled scene (no .kdc magic number)");
    }
    if bytes.len() < FIXED_HEADER {
        bail!("{name}: truncated: {} bytes, shorter than the {FIXED_HEADER}-byte .kdc header", bytes.len());
    }
    let version = u32_at(bytes, 8);
    if version != FORMAT_VERSION {
        bail!("{name}: .kdc format version {version}, but this kdtrace reads version {FORMAT_VERSION}: compile the scene again with `kdtrace compile`");
    }
    let header_len = u32_at(bytes, 12) as u64;
    let payload_len = u64_at(bytes, 16);
    let actual = (bytes.len() - FIXED_HEADER) as u64;
    if payload_len > actual {
        bail!("{name}: truncated: {} bytes, the header says {}", bytes.len(), payload_len.saturating_add(FIXED_HEADER as u64));
    }
    if payload_len < actual {
        bail!("{name}: {} bytes after the end the header states ({} bytes)", actual - payload_len, payload_len + FIXED_HEADER as u64);
    }
    let stored = u64_at(bytes, 24);
    let computed = checksum(bytes);
    if stored != computed {
        bail!("{name}: checksum mismatch (stored {stored:016x}, computed {computed:016x}): the file is corrupted");
    }
    if header_len > payload_len {
        bail!("{name}: header length {header_len} beyond the payload ({payload_len} bytes)");
    }
    let json_end = FIXED_HEADER + header_len as usize;
    let header: Header = serde_json::from_slice(&bytes[FIXED_HEADER..json_end]).map_err(|e| anyhow!("{name}: header: {e}"))?;
    let compiled = sections(&header, &bytes[json_end..]).with_context(|| format!("{name}: invalid compiled scene (written by {})", header.writer))?;
    Ok(KdcScene { compiled, build_settings: header.build_settings, settings: header.settings, writer: header.writer })
}

/// Splits the sections by the header's counts (checked against the bytes before anything is
/// allocated), copies them out and validates them.
fn sections(h: &Header, body: &[u8]) -> Result<Compiled> {
    let c = &h.counts;
    let sizes = [
        ("triangles", c.triangles, size_of::<Triangle>()),
        ("triangle info", c.triangles, size_of::<TriangleInfo>()),
        ("materials", c.materials, size_of::<Material>()),
        ("lights", c.lights, size_of::<Light>()),
        ("nodes", c.nodes, size_of::<KdNode>()),
        ("indices", c.indices, size_of::<u32>()),
    ];
    let mut total = 0u64;
    for (what, count, size) in sizes {
        let bytes = count.checked_mul(size as u64).ok_or_else(|| anyhow!("{what}: count {count} overflows"))?;
        total = total.checked_add(bytes).ok_or_else(|| anyhow!("{what}: section sizes overflow"))?;
    }
    if total != body.len() as u64 {
        bail!("the header's counts need {total} bytes of sections, the file holds {}", body.len());
    }
    // Every count now fits in the file, so the copies below are bounded by its length.
    let mut at = 0usize;
    let mut take = |count: u64, size: usize| {
        let end = at + count as usize * size;
        let s = &body[at..end];
        at = end;
        s
    };
    let triangles: Vec<Triangle> = copy(take(c.triangles, size_of::<Triangle>()));
    let info: Vec<TriangleInfo> = copy(take(c.triangles, size_of::<TriangleInfo>()));
    let materials: Vec<Material> = copy(take(c.materials, size_of::<Material>()));
    let lights: Vec<Light> = copy(take(c.lights, size_of::<Light>()));
    let nodes: Vec<KdNode> = copy(take(c.nodes, size_of::<KdNode>()));
    let indices: Vec<u32> = copy(take(c.indices, size_of::<u32>()));

    if triangles.len() >= 1 << 30 || lights.len() >= u32::MAX as usize || materials.len() >= u32::MAX as usize {
        bail!("too many triangles, lights or materials");
    }
    if h.material_names.len() != materials.len() {
        bail!("{} material names for {} materials", h.material_names.len(), materials.len());
    }
    let bounds = |b: [[f32; 3]; 2], what: &str| -> Result<(Vec3, Vec3)> {
        let (lo, hi) = (Vec3::from(b[0]), Vec3::from(b[1]));
        if !lo.is_finite() || !hi.is_finite() || lo.cmpgt(hi).any() {
            bail!("{what} bounds {lo}..{hi} are not a finite box");
        }
        Ok((lo, hi))
    };
    let (scene_lo, scene_hi) = bounds(h.scene_bounds, "scene")?;
    let (tree_lo, tree_hi) = bounds(h.tree_bounds, "tree")?;
    for (i, t) in triangles.iter().enumerate() {
        for v in [t.v0, t.v1, t.v2] {
            if !v.is_finite() || v.abs().max_element() > MAX_COORDINATE {
                bail!("triangle {i}: vertex {v} not finite or beyond ±{MAX_COORDINATE:e}");
            }
        }
    }
    let rgb_ok = |v: Vec4| v.truncate().is_finite() && v.truncate().min_element() >= 0.0;
    for (i, m) in materials.iter().enumerate() {
        if m.kind != MATERIAL_DIFFUSE {
            bail!("material {i}: unknown kind {}", m.kind);
        }
        if !rgb_ok(m.albedo) || !rgb_ok(m.emission) || !m.params.is_finite() {
            bail!("material {i}: colours must be finite and non-negative");
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
        if !(l.pmf.is_finite() && l.pmf >= 0.0 && l.area.is_finite() && l.area > 0.0 && l.cdf.is_finite() && l.cdf >= previous_cdf && l.cdf <= 1.0) {
            bail!("light {i}: pmf {}, cdf {}, area {} not a valid distribution entry", l.pmf, l.cdf, l.area);
        }
        previous_cdf = l.cdf;
    }
    if let Some(&bad) = indices.iter().find(|&&t| t as usize >= triangles.len()) {
        bail!("k-d tree: triangle index {bad} out of range ({} triangles)", triangles.len());
    }
    let tree = KdTree { nodes, indices, bounds_min: tree_lo, bounds_max: tree_hi, depth: h.tree_depth };
    check_tree(&tree)?;
    let scene = Scene {
        triangles,
        info,
        materials,
        material_names: h.material_names.clone(),
        lights,
        bounds_min: scene_lo,
        bounds_max: scene_hi,
        dropped_degenerate: h.dropped_degenerate,
    };
    Ok(Compiled::new(scene, tree))
}

fn copy<T: Pod>(bytes: &[u8]) -> Vec<T> {
    bytemuck::pod_collect_to_vec(bytes)
}

/// What the traversal relies on: a tree rooted at node 0 whose nodes are each reached exactly
/// once, the below child next in the array and the above child after it, splits finite and
/// inside their node's box, leaf runs inside the index list, depth within the traversal stack.
/// Linear in the node count (`kdbuild::validate` also checks triangle placement, which is far
/// slower and not needed for memory safety).
fn check_tree(t: &KdTree) -> Result<()> {
    if t.nodes.is_empty() {
        bail!("k-d tree has no nodes");
    }
    if t.depth > KD_MAX_DEPTH {
        bail!("k-d tree depth {} beyond {KD_MAX_DEPTH}", t.depth);
    }
    let n = t.nodes.len();
    let mut seen = vec![false; n];
    let mut stack = vec![(0usize, t.bounds_min, t.bounds_max, 0u32)];
    let mut visited = 0usize;
    while let Some((i, lo, hi, depth)) = stack.pop() {
        if depth > KD_MAX_DEPTH {
            bail!("k-d node {i} at depth {depth}, beyond {KD_MAX_DEPTH}");
        }
        let node = *t.nodes.get(i).ok_or_else(|| anyhow!("k-d node index {i} out of range ({n} nodes)"))?;
        if std::mem::replace(&mut seen[i], true) {
            bail!("k-d node {i} is reached twice");
        }
        visited += 1;
        if node.is_leaf() {
            let (first, count) = (node.first_index() as u64, node.count() as u64);
            if first + count > t.indices.len() as u64 {
                bail!("k-d leaf {i}: indices {first}..{} beyond the {} in the list", first + count, t.indices.len());
            }
            continue;
        }
        let (a, s) = (node.axis() as usize, node.split());
        if !(s.is_finite() && s > lo[a] && s < hi[a]) {
            bail!("k-d node {i}: split {s} on axis {a} not inside ({}, {})", lo[a], hi[a]);
        }
        let above = node.above_child() as usize;
        if i + 1 >= n || above <= i + 1 || above >= n {
            bail!("k-d node {i}: children {} and {above} out of range ({n} nodes)", i + 1);
        }
        let (mut below_hi, mut above_lo) = (hi, lo);
        below_hi[a] = s;
        above_lo[a] = s;
        stack.push((i + 1, lo, below_hi, depth + 1));
        stack.push((above, above_lo, hi, depth + 1));
    }
    if visited != n {
        bail!("k-d tree: {} of {n} nodes unreachable", n - visited);
    }
    Ok(())
}
