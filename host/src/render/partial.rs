//! Partial render files (`.kdp`): the fold's nodes (`blocks`) of samples `[A, B)` of every pixel,
//! with what they must agree on to be merged with other parts into one image bit for bit.
//!
//! Layout, all integers little-endian:
//! - 8 bytes `MAGIC`, a u32 `VERSION`, a u32 header length `H`;
//! - `H` bytes of JSON (`Header`): the scene's path and content hash, the settings that change
//!   the image (`ImageSettings`), the samples `[A, B)`, the device, and the nodes in block order
//!   (level, index, first sample, samples);
//! - per node, `width × height` f32 × 4 of sums (radiance `xyz`, zeroed samples in `w`), then as
//!   many of sums of squares. Every pixel holds the node's samples (no adaptive sampling).
//!
//! Reading checks all of it and names the file in every error; nothing in a file can panic.
use crate::render::blocks::{Node, NodeId, Sums, BLOCK_SAMPLES};
use crate::render::Compiled;
use crate::settings::{Aov, RenderSettings, SamplerKind};
use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use shared::glam::Vec4;
use std::io::Write;
use std::path::Path;
use xxhash_rust::xxh3::Xxh3;

/// The file's first bytes.
pub const MAGIC: &[u8; 8] = b"KDTRPART";
/// The format's version: a change of the layout or of `BLOCK_SAMPLES` makes a new one.
pub const VERSION: u32 = 1;

/// Every setting that changes the image's bits, as the render resolved it (the traversal,
/// dispatch and specialisation give the same image bit for bit and are not here).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageSettings {
    pub width: u32,
    pub height: u32,
    pub bounces: u32,
    pub seed: u32,
    pub sampler: SamplerKind,
    pub rr_start: u32,
    /// The constant environment's radiance (an environment map is in the scene's hash).
    pub environment: [f32; 3],
    pub eye: [f64; 3],
    pub target: [f64; 3],
    pub up: [f64; 3],
    pub fov_deg: f32,
    pub aov: Aov,
    pub block_samples: u32,
}

impl ImageSettings {
    pub fn of(s: &RenderSettings) -> Self {
        Self {
            width: s.width,
            height: s.height,
            bounces: s.max_bounces,
            seed: s.seed,
            sampler: s.sampler,
            rr_start: s.rr_start,
            environment: s.environment.to_array(),
            eye: s.camera.eye.to_array(),
            target: s.camera.target.to_array(),
            up: s.camera.up.to_array(),
            fov_deg: s.camera.fov_deg,
            aov: s.aov,
            block_samples: BLOCK_SAMPLES,
        }
    }

    /// The settings that differ from `other`'s, by name, with both values (for refusals).
    pub fn differences(&self, other: &ImageSettings) -> Vec<String> {
        let (a, b) = (serde_json::to_value(self).unwrap_or_default(), serde_json::to_value(other).unwrap_or_default());
        let (Some(a), Some(b)) = (a.as_object(), b.as_object()) else { return vec!["settings".into()] };
        a.iter().filter(|(k, v)| b.get(*k) != Some(v)).map(|(k, v)| format!("{k} {v} vs {}", b[k])).collect()
    }
}

/// The JSON header.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Header {
    /// The scene file as given to `render` (for people; the hash decides).
    pub scene: String,
    /// `scene_hash` of the scene as rendered.
    pub scene_hash: String,
    pub settings: ImageSettings,
    /// Samples `[A, B)` of every pixel.
    pub samples: [u32; 2],
    /// What rendered it (for people).
    pub device: String,
    pub nodes: Vec<NodeId>,
}

/// A partial render: its header and the nodes' sums.
#[derive(Clone, Debug)]
pub struct Partial {
    pub header: Header,
    pub nodes: Vec<Node>,
}

/// A hash of everything in the compiled scene that the integrator reads: geometry, attributes,
/// materials, the light table, the textures (with the environment map and punctual lights), the
/// k-d tree and the local origin. Hex of xxh3-128. The same scene loaded from its OBJ and from
/// a `.kdc` of it hash alike when the tree is the same (a `.kdc` stores the tree it was
/// compiled with, and `--device gpu` builds another tree than the CPU's: such parts differ).
pub fn scene_hash(c: &Compiled) -> String {
    let mut h = Xxh3::new();
    let mut section = |name: &str, bytes: &[u8]| {
        h.update(name.as_bytes());
        h.update(&(bytes.len() as u64).to_le_bytes());
        h.update(bytes);
    };
    section("triangles", bytemuck::cast_slice(&c.scene.triangles));
    section("info", bytemuck::cast_slice(&c.scene.info));
    section("materials", bytemuck::cast_slice(&c.scene.materials));
    section("attributes", bytemuck::cast_slice(&c.scene.attributes));
    section("lights", bytemuck::cast_slice(&c.lights));
    section("light_count", &c.light_count.to_le_bytes());
    section("textures", bytemuck::cast_slice(&c.textures));
    section("environment_map", &c.environment_map.to_le_bytes());
    section("nodes", bytemuck::cast_slice(&c.tree().nodes));
    section("indices", bytemuck::cast_slice(&c.tree().indices));
    section("bounds", bytemuck::cast_slice(&[c.tree().bounds_min, c.tree().bounds_max]));
    section("origin", bytemuck::cast_slice(&c.origin.to_array()));
    section("alpha_masks", &[c.alpha_masks as u8]);
    format!("{:032x}", h.digest128())
}

impl Partial {
    /// Writes the file (the nodes must be those of the header).
    pub fn write(&self, path: &Path) -> Result<()> {
        let file = std::fs::File::create(path).with_context(|| format!("{}: cannot create", path.display()))?;
        let mut out = std::io::BufWriter::new(file);
        self.write_to(&mut out).and_then(|_| out.flush()).with_context(|| format!("{}: cannot write", path.display()))
    }

    /// The file's bytes into `out`.
    pub fn write_to(&self, out: &mut impl Write) -> std::io::Result<()> {
        let header = serde_json::to_vec(&self.header)?;
        out.write_all(MAGIC)?;
        out.write_all(&VERSION.to_le_bytes())?;
        out.write_all(&(header.len() as u32).to_le_bytes())?;
        out.write_all(&header)?;
        for n in &self.nodes {
            for v in n.sums.sum.iter().chain(&n.sums.sum_sq) {
                for c in v.to_array() {
                    out.write_all(&c.to_le_bytes())?;
                }
            }
        }
        Ok(())
    }

    /// Reads and checks a file; every error names it.
    pub fn read(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
        Self::parse(&bytes).with_context(|| format!("{}", path.display()))
    }

    /// Reads a file's header alone and checks it against the file's length (a merge checks
    /// every part's header before it reads any sums, then holds one part's sums at a time).
    pub fn read_header(path: &Path) -> Result<Header> {
        let read = || -> Result<Header> {
            use std::io::Read;
            let mut file = std::fs::File::open(path).context("cannot read")?;
            let len = file.metadata().context("cannot read")?.len();
            let mut prefix = Vec::new();
            (&mut file).take(16).read_to_end(&mut prefix).context("cannot read")?;
            if prefix.len() == 16 {
                let header_len = u32::from_le_bytes([prefix[12], prefix[13], prefix[14], prefix[15]]) as u64;
                // No more than the file holds: a crafted length allocates nothing.
                file.take(header_len.min(len.saturating_sub(16))).read_to_end(&mut prefix).context("cannot read")?;
            }
            Ok(parse_header(&prefix, len)?.0)
        };
        read().with_context(|| format!("{}", path.display()))
    }

    /// Parses a file's bytes (`read` names the file in the error).
    pub fn parse(bytes: &[u8]) -> Result<Self> {
        let (header, data_at) = parse_header(bytes, bytes.len() as u64)?;
        let s = &header.settings;
        let node_bytes = s.width as usize * s.height as usize * 2 * 16;
        let data = &bytes[data_at..];
        let floats = |chunk: &[u8]| -> Vec<Vec4> {
            chunk
                .as_chunks::<16>()
                .0
                .iter()
                .map(|p| {
                    let f = |i: usize| f32::from_le_bytes([p[i], p[i + 1], p[i + 2], p[i + 3]]);
                    Vec4::new(f(0), f(4), f(8), f(12))
                })
                .collect()
        };
        let nodes = header
            .nodes
            .iter()
            .zip(data.chunks_exact(node_bytes))
            .map(|(&id, chunk)| {
                let (sum, sum_sq) = chunk.split_at(chunk.len() / 2);
                Node { id, sums: Sums { sum: floats(sum), sum_sq: floats(sum_sq) } }
            })
            .collect();
        Ok(Self { header, nodes })
    }
}

/// The header from a file's first bytes (`bytes`, at least through the header, else it is
/// truncated) and the file's length `len`, checked against each other; and where the sums start.
fn parse_header(bytes: &[u8], len: u64) -> Result<(Header, usize)> {
    if bytes.len() < 16 || &bytes[..8] != MAGIC {
        bail!("not a kdtrace partial render (no {:?} at its start)", std::str::from_utf8(MAGIC).unwrap_or(""));
    }
    let word = |at: usize| u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
    let version = word(8);
    if version != VERSION {
        bail!("partial render format version {version}; this kdtrace reads version {VERSION}");
    }
    let header_len = word(12) as usize;
    let Some(header_bytes) = bytes.get(16..16 + header_len) else {
        bail!("truncated: the header needs {header_len} bytes, the file has {} after its start", len - 16);
    };
    let header: Header = serde_json::from_slice(header_bytes).context("the header is not valid")?;
    let s = &header.settings;
    if s.block_samples != BLOCK_SAMPLES {
        bail!("rendered in blocks of {} samples; this kdtrace folds blocks of {BLOCK_SAMPLES}", s.block_samples);
    }
    let pixels = s.width as u64 * s.height as u64;
    if pixels == 0 || s.width > crate::settings::MAX_SIDE || s.height > crate::settings::MAX_SIDE {
        bail!("image size {}x{} is not one kdtrace renders", s.width, s.height);
    }
    check_nodes(&header)?;
    let data = len - 16 - header_len as u64;
    let want = pixels * 2 * 16 * header.nodes.len() as u64;
    if data != want {
        bail!(
            "{data} bytes of sums for {} node(s) of {}x{} pixels, which need {want}{}",
            header.nodes.len(),
            s.width,
            s.height,
            if data < want { " (truncated)" } else { "" }
        );
    }
    Ok((header, 16 + header_len))
}

/// The header's nodes: valid, in order, covering its samples with no gap or overlap.
fn check_nodes(header: &Header) -> Result<()> {
    let [a, b] = header.samples;
    if a >= b || !a.is_multiple_of(BLOCK_SAMPLES) {
        bail!("samples {a}..{b}: not a range starting on a block of {BLOCK_SAMPLES}");
    }
    let mut end = a;
    for id in &header.nodes {
        id.check()?;
        if id.first != end {
            bail!("its nodes do not cover samples {a}..{b}: node {id:?} follows sample {end}");
        }
        end = id.end();
    }
    if end != b {
        bail!("its nodes cover samples {a}..{end}, its header says {a}..{b}");
    }
    Ok(())
}

/// Checks a partial render's range before rendering: `[a, b)` starting on a block.
pub fn check_range(a: u32, b: u32) -> Result<()> {
    if a >= b {
        bail!("--samples {a}..{b} holds no sample");
    }
    if !a.is_multiple_of(BLOCK_SAMPLES) {
        bail!(
            "--samples {a}..{b}: a part must start on a block of {BLOCK_SAMPLES} samples (a multiple of \
             {BLOCK_SAMPLES}, e.g. {}..{b}); it may end anywhere, but a part ending inside a block is the render's last",
            a - a % BLOCK_SAMPLES
        );
    }
    if b > crate::settings::MAX_SPP {
        bail!("--samples {a}..{b} goes past {} samples per pixel", crate::settings::MAX_SPP);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::settings::camera::Camera;
    use shared::glam::DVec3;

    fn part() -> Partial {
        let camera = Camera { eye: DVec3::new(0.0, 1.0, 3.0), target: DVec3::ZERO, up: DVec3::Y, fov_deg: 40.0 };
        let s = RenderSettings { width: 3, height: 2, ..RenderSettings::with_camera(camera) };
        let ids = [NodeId { level: 1, index: 1, first: 16, samples: 16 }, NodeId::block(4, 5)];
        let nodes: Vec<Node> = ids
            .iter()
            .enumerate()
            .map(|(i, &id)| {
                let mut sums = Sums::zero(6);
                sums.sum[i] = Vec4::new(1.5, -0.0, f32::MIN_POSITIVE, 2.0);
                sums.sum_sq[5 - i] = Vec4::splat(3.25);
                Node { id, sums }
            })
            .collect();
        let header = Header {
            scene: "s.obj".into(),
            scene_hash: "00".into(),
            settings: ImageSettings::of(&s),
            samples: [16, 37],
            device: "test".into(),
            nodes: ids.to_vec(),
        };
        Partial { header, nodes }
    }

    fn bytes(p: &Partial) -> Vec<u8> {
        let mut b = Vec::new();
        p.write_to(&mut b).unwrap();
        b
    }

    #[test]
    fn a_file_reads_back_bit_for_bit() {
        let p = part();
        let q = Partial::parse(&bytes(&p)).unwrap();
        assert_eq!(q.header.nodes, p.header.nodes);
        for (a, b) in p.nodes.iter().zip(&q.nodes) {
            let bits =
                |s: &Sums| s.sum.iter().chain(&s.sum_sq).map(|v| v.to_array().map(f32::to_bits)).collect::<Vec<_>>();
            assert_eq!(bits(&a.sums), bits(&b.sums));
        }
    }

    #[test]
    fn damaged_files_are_errors_not_panics() {
        let good = bytes(&part());
        let err = |b: &[u8]| format!("{:#}", Partial::parse(b).unwrap_err());
        assert!(err(b"KDTR").contains("not a kdtrace partial"));
        assert!(err(&good[..good.len() - 1]).contains("truncated"));
        for cut in [8, 12, 16, 40] {
            assert!(Partial::parse(&good[..cut]).is_err());
        }
        let mut v2 = good.clone();
        v2[8] = 2;
        assert!(err(&v2).contains("version 2"));
        let mut long = good.clone();
        long.push(0);
        assert!(err(&long).contains("need"));
        let mut bad_len = good.clone();
        bad_len[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(err(&bad_len).contains("truncated"));
        // A header whose nodes leave a gap.
        let mut p = part();
        p.header.nodes[1] = NodeId::block(5, 5);
        p.header.samples = [16, 45];
        assert!(err(&bytes(&p)).contains("do not cover"));
    }

    #[test]
    fn a_range_must_start_on_a_block() {
        assert!(check_range(0, 5).is_ok());
        assert!(check_range(8, 64).is_ok());
        assert!(format!("{}", check_range(3, 64).unwrap_err()).contains("multiple of 8"));
        assert!(check_range(8, 8).is_err());
    }
}
