//! Crafting `.kdc` files for tests: a valid file's pieces, edited and resealed with a correct
//! checksum, so that the checks behind the checksum are what refuses them.
#![allow(dead_code)]
use kdtrace::render::{kdc, kdc::FIXED_HEADER};

/// A `.kdc` file taken apart: its JSON header and its section bytes.
pub struct Parts {
    pub version: u32,
    pub header: serde_json::Value,
    pub body: Vec<u8>,
}

pub fn split(bytes: &[u8]) -> Parts {
    let version = u32::from_le_bytes(bytes[8..12].try_into().unwrap());
    let header_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let header = serde_json::from_slice(&bytes[FIXED_HEADER..FIXED_HEADER + header_len]).unwrap();
    Parts { version, header, body: bytes[FIXED_HEADER + header_len..].to_vec() }
}

/// Puts a file together again with a correct checksum.
pub fn join(p: &Parts) -> Vec<u8> {
    let mut json = serde_json::to_vec(&p.header).unwrap();
    json.resize(json.len().next_multiple_of(16), b' ');
    let mut out = Vec::new();
    out.extend_from_slice(&kdc::MAGIC);
    out.extend_from_slice(&p.version.to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&((json.len() + p.body.len()) as u64).to_le_bytes());
    out.extend_from_slice(&0u64.to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(&p.body);
    kdc::seal(&mut out);
    out
}

/// Byte offset in the body of section `which` (0 triangles, 1 info, 2 materials, 3 lights,
/// 4 nodes, 5 indices, 6 vertex attributes, 7 textures, 8 environment texels).
pub fn section_offset(p: &Parts, which: usize) -> usize {
    let c = &p.header["counts"];
    let n = |k: &str| c[k].as_u64().unwrap() as usize;
    let sizes = [
        n("triangles") * 48,
        n("triangles") * 8,
        n("materials") * std::mem::size_of::<shared::layout::Material>(),
        n("lights") * 16,
        n("nodes") * 8,
        n("indices") * 4,
        n("attributes") * std::mem::size_of::<shared::layout::TriangleAttributes>(),
        n("texture_words") * 4,
        n("environment_texels") * 12,
    ];
    sizes[..which].iter().sum()
}

pub fn put_u32(p: &mut Parts, at: usize, v: u32) {
    p.body[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

pub fn put_f32(p: &mut Parts, at: usize, v: f32) {
    p.body[at..at + 4].copy_from_slice(&v.to_le_bytes());
}
