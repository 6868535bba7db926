//! glTF test support: loading and rendering at small sizes, and glTF files written by the tests
//! (a textured quad with data URIs, a lit quad with a punctual light, a clear slab), for
//! `tests/gltf.rs` and `tests/gltf_lights_and_media.rs`.
#![allow(dead_code)]
use base64::Engine;
use kdtrace::kdbuild::BuildSettings;
use kdtrace::render::load::load_with_camera;
use kdtrace::render::{cpu, Rendered};
use kdtrace::scene::texture::srgb_to_linear;
use kdtrace::settings::{Aov, RenderSettings, SceneSettings};
use kdtrace::Loaded;
use shared::glam::{DVec3, Vec4};
use std::path::{Path, PathBuf};

pub fn none(_: u64, _: u64) {}

pub fn data(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/data/gltf").join(rel)
}

pub fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("kdtrace-gltf-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

pub fn load(path: &Path, camera: Option<&str>) -> Loaded {
    load_with_camera(path, BuildSettings::default(), camera).unwrap()
}

/// The loaded scene's own settings (its camera) with `flags` over them, resolved.
pub fn settings(l: &Loaded, flags: SceneSettings) -> RenderSettings {
    let (lo, hi) = l.compiled.world_bounds();
    l.settings.overridden_by(&flags).resolve(lo, hi).unwrap()
}

pub fn small(side_w: u32, side_h: u32, spp: u32) -> SceneSettings {
    SceneSettings { width: Some(side_w), height: Some(side_h), spp: Some(spp), seed: Some(1), ..Default::default() }
}

pub fn bits(r: &Rendered) -> Vec<u32> {
    r.sum.iter().chain(&r.sum_sq).flat_map(|p: &Vec4| p.to_array().map(f32::to_bits)).collect()
}

/// The pixel (column, row) that world point `p` projects to.
pub fn project(s: &RenderSettings, p: DVec3) -> (usize, usize) {
    let c = &s.camera;
    let f = (c.target - c.eye).normalize();
    let r = f.cross(c.up).normalize();
    let u = r.cross(f);
    let d = p - c.eye;
    let t = ((c.fov_deg as f64).to_radians() * 0.5).tan();
    let aspect = s.width as f64 / s.height as f64;
    let x = d.dot(r) / d.dot(f) / (t * aspect);
    let y = d.dot(u) / d.dot(f) / t;
    (((x + 1.0) * 0.5 * s.width as f64) as usize, ((1.0 - y) * 0.5 * s.height as f64) as usize)
}

pub fn pixel(r: &Rendered, x: usize, y: usize) -> [f32; 3] {
    r.mean()[y * r.width as usize + x]
}

pub fn linear(c: [u8; 3]) -> [f32; 3] {
    c.map(|v| srgb_to_linear(v as f64 / 255.0) as f32)
}

/// Quadrant colours of the test texture: top left, top right, bottom left, bottom right (sRGB).
pub const QUADRANTS: [[u8; 3]; 4] = [[255, 0, 0], [0, 255, 0], [0, 0, 255], [128, 128, 128]];

pub fn png_quadrants() -> Vec<u8> {
    png_quadrants_alpha(255)
}

/// The quadrant image with the top left quadrant's alpha `a` (the rest opaque).
pub fn png_quadrants_alpha(a: u8) -> Vec<u8> {
    let img = image::RgbaImage::from_fn(16, 16, |x, y| {
        let q = 2 * (y >= 8) as usize + (x >= 8) as usize;
        let c = QUADRANTS[q];
        image::Rgba([c[0], c[1], c[2], if q == 0 { a } else { 255 }])
    });
    let mut bytes = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png).unwrap();
    bytes
}

pub fn b64(bytes: &[u8]) -> String {
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

/// A glTF file: a square from (−1, −1) to (1, 1) at z = 0 (uv (0, 0) at its top left corner,
/// glTF's), textured with the quadrant image, as mesh 0 of node `mesh_node` (a JSON object
/// text without its mesh key), a camera at (0, 0, 3) relative to `camera_parent` (translation
/// JSON), all in one file with data URIs. `mode` 4 (triangles), 5 (strip) or 6 (fan).
pub fn quad_gltf(mesh_node: &str, camera_translation: &str, transform: &str, mode: u32) -> String {
    quad_gltf_with(mesh_node, camera_translation, transform, mode, "", &png_quadrants())
}

/// `quad_gltf` with `material` JSON members added to the material and the image `png`.
pub fn quad_gltf_with(
    mesh_node: &str,
    camera_translation: &str,
    transform: &str,
    mode: u32,
    material: &str,
    png: &[u8],
) -> String {
    let positions: [[f32; 3]; 4] = [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]];
    let uvs: [[f32; 2]; 4] = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
    let indices: Vec<u16> = match mode {
        4 => vec![0, 1, 2, 0, 2, 3],
        5 => vec![0, 1, 3, 2],
        _ => vec![0, 1, 2, 3],
    };
    let mut buf = Vec::new();
    for p in positions.iter().flatten().chain(uvs.iter().flatten()) {
        buf.extend(p.to_le_bytes());
    }
    for i in &indices {
        buf.extend(i.to_le_bytes());
    }
    let n = indices.len();
    format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "extensionsUsed": ["KHR_texture_transform"],
  "scene": 0,
  "scenes": [{{"nodes": [0, 1]}}],
  "nodes": [{{"mesh": 0, {mesh_node}}}, {{"camera": 0, "translation": {camera_translation}}}],
  "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.6, "znear": 0.01}}}}],
  "meshes": [{{"name": "quad", "primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1}}, "indices": 2, "material": 0, "mode": {mode}}}]}}],
  "materials": [{{{material}"pbrMetallicRoughness": {{"baseColorTexture": {{"index": 0{transform}}}, "metallicFactor": 0}}}}],
  "textures": [{{"source": 0}}],
  "images": [{{"uri": "data:image/png;base64,{png}"}}],
  "buffers": [{{"byteLength": {len}, "uri": "data:application/octet-stream;base64,{data}"}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 32}},
                  {{"buffer": 0, "byteOffset": 80, "byteLength": {ib}}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, -1, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}},
    {{"bufferView": 2, "componentType": 5123, "count": {n}, "type": "SCALAR"}}
  ]
}}"#,
        png = b64(png),
        len = buf.len(),
        data = b64(&buf),
        ib = 2 * n,
    )
}

/// The albedo of the quad's four quadrants as the file's camera sees them.
pub fn quadrant_albedo(path: &Path) -> [[f32; 3]; 4] {
    let l = load(path, None);
    let s = RenderSettings { aov: Aov::Albedo, ..settings(&l, small(16, 16, 4)) };
    let r = cpu::render(&l.compiled, &s, &none).unwrap();
    // tan(0.3) · 3 = 0.93: the quad fills the view; (4, 4) lies well inside the top left quadrant.
    [(4, 4), (11, 4), (4, 11), (11, 11)].map(|(x, y)| pixel(&r, x, y))
}

pub fn close(a: [f32; 3], b: [f32; 3]) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() < 2e-3)
}

/// A glTF file: the square from (−1, −1) to (1, 1) at z = 0 in a grey rough dielectric, seen by a
/// camera at (0, 0, 3), and one KHR_lights_punctual light `light` (a JSON object) on a node with
/// the members `light_node` (its transform).
pub fn lit_quad_gltf(light: &str, light_node: &str) -> String {
    let material = r#"{"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0, "roughnessFactor": 1}}"#;
    lit_quad_gltf_with(light, light_node, material)
}

/// `lit_quad_gltf` with the quad's `material` (a JSON object).
pub fn lit_quad_gltf_with(light: &str, light_node: &str, material: &str) -> String {
    let positions: [[f32; 3]; 4] = [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]];
    let mut buf: Vec<u8> = positions.iter().flatten().flat_map(|p| p.to_le_bytes()).collect();
    for i in [0u16, 1, 2, 0, 2, 3] {
        buf.extend(i.to_le_bytes());
    }
    format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "extensionsUsed": ["KHR_lights_punctual"],
  "extensions": {{"KHR_lights_punctual": {{"lights": [{light}]}}}},
  "scene": 0,
  "scenes": [{{"nodes": [0, 1, 2]}}],
  "nodes": [{{"mesh": 0}}, {{"camera": 0, "translation": [0, 0, 3]}},
            {{"extensions": {{"KHR_lights_punctual": {{"light": 0}}}}, {light_node}}}],
  "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.6, "znear": 0.01}}}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}],
  "materials": [{material}],
  "buffers": [{{"byteLength": {len}, "uri": "data:application/octet-stream;base64,{data}"}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 12}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, -1, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}}
  ]
}}"#,
        len = buf.len(),
        data = b64(&buf),
    )
}

/// A glTF file: a clear slab (white transmissive principled, index 1.5, smooth) from (−1, −1,
/// −0.25) to (1, 1, 0.25), its `volume` (KHR_materials_volume members, or none), seen along −z by
/// a camera at (0, 0, 3).
pub fn slab_gltf(volume: &str) -> String {
    let h = 0.25f32;
    let v: [[f32; 3]; 8] = [
        [-1.0, -1.0, -h],
        [1.0, -1.0, -h],
        [1.0, 1.0, -h],
        [-1.0, 1.0, -h],
        [-1.0, -1.0, h],
        [1.0, -1.0, h],
        [1.0, 1.0, h],
        [-1.0, 1.0, h],
    ];
    // Counter-clockwise seen from outside.
    let faces: [u16; 36] =
        [4, 5, 6, 4, 6, 7, 0, 2, 1, 0, 3, 2, 1, 2, 6, 1, 6, 5, 0, 4, 7, 0, 7, 3, 3, 7, 6, 3, 6, 2, 0, 1, 5, 0, 5, 4];
    let mut buf: Vec<u8> = v.iter().flatten().flat_map(|p| p.to_le_bytes()).collect();
    for i in faces {
        buf.extend(i.to_le_bytes());
    }
    let extensions = if volume.is_empty() {
        r#""KHR_materials_transmission": {"transmissionFactor": 1}"#.to_string()
    } else {
        format!(r#""KHR_materials_transmission": {{"transmissionFactor": 1}}, "KHR_materials_volume": {{{volume}}}"#)
    };
    format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_volume"],
  "scene": 0,
  "scenes": [{{"nodes": [0, 1]}}],
  "nodes": [{{"mesh": 0}}, {{"camera": 0, "translation": [0, 0, 3]}}],
  "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.3, "znear": 0.01}}}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}],
  "materials": [{{"pbrMetallicRoughness": {{"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0, "roughnessFactor": 0}},
                  "extensions": {{{extensions}}}}}],
  "buffers": [{{"byteLength": {len}, "uri": "data:application/octet-stream;base64,{data}"}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 96}}, {{"buffer": 0, "byteOffset": 96, "byteLength": 72}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3", "min": [-1, -1, -0.25], "max": [1, 1, 0.25]}},
    {{"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}}
  ]
}}"#,
        len = buf.len(),
        data = b64(&buf),
    )
}
