//! glTF 2.0 (`.gltf` with its buffers and images, data URIs included, and `.glb`) through the
//! `gltf` crate: the default scene's node hierarchy with every transform composed in f64, its
//! meshes (triangles, strips and fans), vertex normals and TEXCOORD_0, the metallic-roughness
//! materials as `principled` ones, perspective cameras and KHR_lights_punctual lights (point,
//! spot and directional: delta lights, reached by next-event estimation only).
//!
//! Node transforms are read from the JSON text as f64 (the `gltf` crate reads them as f32), so a
//! node at survey coordinates keeps its digits until the scene is moved to its local frame, as an
//! OBJ's vertices do. Accessors are read here, not through the crate's reader: every count, offset
//! and stride is checked against its buffer, and every index against its vertices, so a broken
//! file is an error naming the file, mesh and primitive, never a panic.
//!
//! Texture coordinates: glTF's v runs top to bottom (image row 0 at v = 0); `shared::texture`
//! reads v bottom to top (OBJ's `vt`), so v becomes 1 − v once the KHR_texture_transform of the
//! material, if any, has been applied in glTF's own frame.
use crate::files::Files;
use crate::scene::obj::{Mesh, MAX_COORDINATE};
use crate::scene::texture::{Kind, TextureSet};
use crate::scene::{clearcoat, principled, Principled, PunctualLight, WorldAttributes, WorldScene};
use crate::settings::SceneSettings;
use ::gltf::mesh::Mode;
use anyhow::{anyhow, bail, Result};
use base64::Engine;
use shared::glam::{DMat3, DMat4, DQuat, DVec3, Vec3};
use shared::layout::{
    Material, ALPHA_BLEND, ALPHA_CUTOFF, NO_TEXTURE, TEXTURE_ALBEDO, TEXTURE_ALPHA, TEXTURE_CLEARCOAT,
    TEXTURE_EMISSION, TEXTURE_METALLIC, TEXTURE_NORMAL, TEXTURE_ROUGHNESS,
};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

mod buffers;
mod material;
use buffers::*;
use material::*;

/// Extensions whose effect is rendered.
pub const SUPPORTED_EXTENSIONS: [&str; 8] = [
    "KHR_texture_transform",
    "KHR_mesh_quantization",
    "KHR_materials_clearcoat",
    "KHR_materials_emissive_strength",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_volume",
    "KHR_lights_punctual",
];

/// A camera placed by a node, in world coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfCamera {
    /// The camera's index in the file's `cameras`.
    pub index: usize,
    pub name: Option<String>,
    pub eye: DVec3,
    pub target: DVec3,
    pub up: DVec3,
    /// Vertical field of view in degrees; `None` for an orthographic camera.
    pub fov_deg: Option<f64>,
    pub aspect: Option<f64>,
}

impl GltfCamera {
    fn label(&self) -> String {
        match &self.name {
            Some(n) => format!("camera {} ({n:?})", self.index),
            None => format!("camera {}", self.index),
        }
    }
}

/// A glTF file read: its triangles and materials (as an OBJ's) with its KHR_lights_punctual
/// lights in `mesh.scene.punctual_lights`, and its cameras.
#[derive(Clone, Debug)]
pub struct GltfScene {
    pub mesh: Mesh,
    pub cameras: Vec<GltfCamera>,
}

impl GltfScene {
    /// The render settings of camera `choice` (its index, or its name), or of the first
    /// perspective camera when there is no choice (none at all: the framing default), with the
    /// camera's aspect ratio where it gives one. An orthographic camera is an error naming it.
    pub fn camera_settings(
        &self,
        path: &Path,
        choice: Option<&str>,
    ) -> Result<(SceneSettings, Option<f64>, Vec<String>)> {
        let mut warnings = Vec::new();
        let camera = match choice {
            Some(c) => {
                let by_index = c.parse::<usize>().ok();
                let found = self
                    .cameras
                    .iter()
                    .find(|k| Some(k.index) == by_index)
                    .or_else(|| self.cameras.iter().find(|k| k.name.as_deref() == Some(c)));
                let Some(found) = found else {
                    let known: Vec<String> = self.cameras.iter().map(GltfCamera::label).collect();
                    bail!(
                        "{}: no camera {c:?} placed in the scene (cameras: {})",
                        path.display(),
                        if known.is_empty() { "none".into() } else { known.join(", ") }
                    );
                };
                if found.fov_deg.is_none() {
                    bail!(
                        "{}: {} is orthographic; kdtrace renders perspective cameras only",
                        path.display(),
                        found.label()
                    );
                }
                Some(found)
            }
            None => {
                let first = self.cameras.iter().find(|k| k.fov_deg.is_some());
                if first.is_none() && !self.cameras.is_empty() {
                    warnings.push(format!(
                        "{}: only orthographic cameras ({}), which kdtrace does not render; the default framing is used",
                        path.display(),
                        self.cameras.iter().map(GltfCamera::label).collect::<Vec<_>>().join(", ")
                    ));
                }
                first
            }
        };
        let mut s = SceneSettings::default();
        if let Some(c) = camera {
            s.eye = Some(c.eye.to_array());
            s.target = Some(c.target.to_array());
            s.up = Some(c.up.to_array());
            s.fov_deg = c.fov_deg.map(|f| f as f32);
            if let Some(a) = c.aspect {
                let (w, h) = if a >= 1.0 {
                    (
                        crate::settings::DEFAULT_WIDTH,
                        (crate::settings::DEFAULT_WIDTH as f64 / a).round().max(1.0) as u32,
                    )
                } else {
                    (
                        (crate::settings::DEFAULT_HEIGHT as f64 * a).round().max(1.0) as u32,
                        crate::settings::DEFAULT_HEIGHT,
                    )
                };
                s.width = Some(w);
                s.height = Some(h);
            }
        }
        Ok((s, camera.and_then(|c| c.aspect), warnings))
    }
}

/// Reads a glTF file (`.gltf` or `.glb`), its buffers and images, through `files`.
pub fn load(path: &Path, files: &dyn Files) -> Result<GltfScene> {
    let bytes = files.read(path).map_err(|e| anyhow!("{}: cannot read: {e}", path.display()))?;
    parse(path, &bytes, files)
}

/// The 3×3 matrix of a KHR_texture_transform (T·R·S, glTF's texture frame) as (a, b, c; d, e, f).
#[derive(Clone, Copy, Debug, PartialEq)]
struct UvTransform([f64; 6]);

impl UvTransform {
    const IDENTITY: Self = Self([1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);

    fn of(info: &::gltf::texture::Info) -> Self {
        match info.texture_transform() {
            None => Self::IDENTITY,
            Some(t) => {
                let [ox, oy] = t.offset().map(|x| x as f64);
                let [sx, sy] = t.scale().map(|x| x as f64);
                let r = t.rotation() as f64;
                let (s, c) = r.sin_cos();
                // translation · rotation · scale with rotation [c s; −s c] (the extension's).
                Self([c * sx, s * sy, ox, -s * sx, c * sy, oy])
            }
        }
    }

    fn apply(&self, [u, v]: [f64; 2]) -> [f64; 2] {
        let m = self.0;
        [m[0] * u + m[1] * v + m[2], m[3] * u + m[4] * v + m[5]]
    }
}

/// What a glTF material becomes: ours, the UV transform its textures share, whether its faces
/// are cut out entirely (a constant alpha below the cutoff).
struct MaterialOut {
    material: Material,
    uv: UvTransform,
    invisible: bool,
}

/// Parses a glTF or GLB file's bytes; `path` names it and locates its buffers and images.
pub fn parse(path: &Path, bytes: &[u8], files: &dyn Files) -> Result<GltfScene> {
    let p = path.display();
    // The JSON for the checks the crate does not make (required extensions, with a message of
    // ours) and for node transforms in f64.
    let (json_bytes, blob): (Vec<u8>, Option<Vec<u8>>) = if bytes.starts_with(b"glTF") {
        let glb = ::gltf::binary::Glb::from_slice(bytes).map_err(|e| anyhow!("{p}: not a valid GLB file: {e}"))?;
        (glb.json.into_owned(), glb.bin.map(|b| b.into_owned()))
    } else {
        (crate::files::without_bom(bytes).to_vec(), None)
    };
    let json: serde_json::Value =
        serde_json::from_slice(&json_bytes).map_err(|e| anyhow!("{p}: not glTF JSON: {e}"))?;
    let list = |key: &str| -> Vec<String> {
        json[key]
            .as_array()
            .map(|a| a.iter().filter_map(|v| v.as_str().map(String::from)).collect())
            .unwrap_or_default()
    };
    for ext in list("extensionsRequired") {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            bail!("{p}: requires the glTF extension {ext}, which kdtrace does not support");
        }
    }
    let mut warnings = Vec::new();
    for ext in list("extensionsUsed") {
        if SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            continue;
        }
        warnings.push(format!("{p}: glTF extension {ext}: not supported, ignored"));
    }
    let document = ::gltf::Gltf::from_slice_without_validation(&json_bytes)
        .map_err(|e| anyhow!("{p}: not a glTF 2.0 file: {e}"))?
        .document;
    // The crate's validation (indices in range, required fields), with its path to the problem.
    {
        let root = document.as_json();
        // gltf-json's own check of POSITION's min and max indexes the accessors unchecked.
        for (m, mesh) in root.meshes.iter().enumerate() {
            for (k, prim) in mesh.primitives.iter().enumerate() {
                for (semantic, index) in &prim.attributes {
                    if index.value() >= root.accessors.len() {
                        bail!(
                            "{p}: invalid glTF: meshes[{m}].primitives[{k}].attributes[\"{}\"]: accessor {} does \
                             not exist ({} accessors)",
                            semantic.to_string(),
                            index.value(),
                            root.accessors.len()
                        );
                    }
                }
            }
        }
        let mut problems = Vec::new();
        use ::gltf::json::validation::Validate;
        root.validate(root, ::gltf::json::Path::new, &mut |path, error| {
            let path = path().to_string();
            // Readers never need POSITION's bounds (exporters do leave them out): not an error here.
            let bounds = path.ends_with(".min") || path.ends_with(".max");
            // Required extensions are checked against kdtrace's own list above; the crate knows
            // fewer (not KHR_materials_volume, KHR_materials_clearcoat, KHR_mesh_quantization).
            let required = path.starts_with("extensionsRequired");
            use ::gltf::json::validation::Error;
            if !(bounds && error == Error::Missing) && !(required && error == Error::Unsupported) {
                problems.push(format!("{path}: {error}"));
            }
        });
        if !problems.is_empty() {
            bail!("{p}: invalid glTF: {}", problems.join("; "));
        }
    }
    // Buffers.
    let mut buffers = Vec::new();
    for b in document.buffers() {
        let what = format!("buffer {}", b.index());
        let data = match b.source() {
            ::gltf::buffer::Source::Bin => {
                blob.clone().ok_or_else(|| anyhow!("{p}: {what} is the GLB binary chunk, which this file lacks"))?
            }
            ::gltf::buffer::Source::Uri(uri) => read_uri(path, uri, files, &what)?,
        };
        if data.len() < b.length() {
            bail!("{p}: {what} holds {} bytes, fewer than its byteLength {}", data.len(), b.length());
        }
        buffers.push(data);
    }
    // Materials (the default material last).
    let mut textures = TextureSet::default();
    let mut outs = Vec::new();
    let mut names = Vec::new();
    let mut notes: BTreeSet<String> = BTreeSet::new();
    for m in document.materials() {
        let label = match m.name() {
            Some(n) => format!("material {} ({n:?})", m.index().unwrap_or(0)),
            None => format!("material {}", m.index().unwrap_or(0)),
        };
        outs.push(material(path, &document, &buffers, files, &m, &label, &mut textures, &mut notes)?);
        names.push(m.name().map_or_else(|| format!("material{}", m.index().unwrap_or(0)), String::from));
    }
    let default_material = outs.len() as u32;
    // The specification's default: white, fully metallic, fully rough.
    let p_default = Principled { base_color: Vec3::ONE, metallic: 1.0, roughness: 1.0, transmission: 0.0, ior: 1.5 };
    outs.push(MaterialOut {
        material: principled(&p_default, Vec3::ZERO),
        uv: UvTransform::IDENTITY,
        invisible: false,
    });
    names.push("default".into());

    // The scene's nodes, depth first, with world transforms.
    let scene = document.default_scene().or_else(|| document.scenes().next());
    let Some(scene) = scene else { bail!("{p}: no scene to render (the file defines none)") };
    let mut stack: Vec<(::gltf::Node, DMat4, usize)> = Vec::new();
    for n in scene.nodes() {
        stack.push((n, DMat4::IDENTITY, 0));
    }
    let mut triangles = Vec::new();
    let mut material_of = Vec::new();
    let mut attributes: Vec<WorldAttributes> = Vec::new();
    let mut any_attributes = false;
    let mut cameras = Vec::new();
    let mut lights = Vec::new();
    let mut cut = 0usize;
    let mut visits = 0usize;
    while let Some((node, parent, depth)) = stack.pop() {
        visits += 1;
        if depth > 256 || visits > 1 << 22 {
            bail!("{p}: the node hierarchy is cyclic or deeper than 256 levels (node {})", node.index());
        }
        let world = parent * node_matrix(path, &json, node.index())?;
        let children: Vec<_> = node.children().collect();
        for c in children.into_iter().rev() {
            stack.push((c, world, depth + 1));
        }
        let linear = DMat3::from_mat4(world);
        if let Some(c) = node.camera() {
            let eye = world.transform_point3(DVec3::ZERO);
            let forward = linear * DVec3::NEG_Z;
            let up = linear * DVec3::Y;
            if forward.length() == 0.0 || up.length() == 0.0 || !eye.is_finite() {
                bail!("{p}: node {}: camera {} has a degenerate transform", node.index(), c.index());
            }
            let (fov_deg, aspect) = match c.projection() {
                ::gltf::camera::Projection::Perspective(q) => (
                    Some((q.yfov() as f64).to_degrees()),
                    q.aspect_ratio().map(|a| a as f64).filter(|a| *a > 0.0 && a.is_finite()),
                ),
                ::gltf::camera::Projection::Orthographic(_) => (None, None),
            };
            if let Some(f) = fov_deg {
                if !(f > 0.0 && f < 180.0) {
                    bail!("{p}: camera {}: yfov of {f}° is outside (0, 180)", c.index());
                }
            }
            cameras.push(GltfCamera {
                index: c.index(),
                name: c.name().map(String::from),
                eye,
                target: eye + forward.normalize(),
                up: up.normalize(),
                fov_deg,
                aspect,
            });
        }
        if let Some(l) = node.light() {
            lights.push(light_of(&p.to_string(), node.index(), &l, world, linear, &mut warnings)?);
        }
        let Some(mesh) = node.mesh() else { continue };
        let mirrors = linear.determinant() < 0.0;
        let normal_matrix = linear.inverse().transpose();
        let mesh_label = match mesh.name() {
            Some(n) => format!("mesh {} ({n:?})", mesh.index()),
            None => format!("mesh {}", mesh.index()),
        };
        for prim in mesh.primitives() {
            let at = format!("{p}: {mesh_label} primitive {} (node {})", prim.index(), node.index());
            let mode = prim.mode();
            if matches!(mode, Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip) {
                bail!("{at}: {mode:?} primitives are not supported (kdtrace renders triangles)");
            }
            let pos = prim.get(&::gltf::Semantic::Positions).ok_or_else(|| anyhow!("{at}: no POSITION attribute"))?;
            let positions = read_accessor(&buffers, &pos, 3, "POSITION").map_err(|e| anyhow!("{at}: {e}"))?;
            let vertices = positions.len() / 3;
            let normals = match prim.get(&::gltf::Semantic::Normals) {
                Some(a) => Some(read_accessor(&buffers, &a, 3, "NORMAL").map_err(|e| anyhow!("{at}: {e}"))?),
                None => None,
            };
            let uvs = match prim.get(&::gltf::Semantic::TexCoords(0)) {
                Some(a) => Some(read_accessor(&buffers, &a, 2, "TEXCOORD_0").map_err(|e| anyhow!("{at}: {e}"))?),
                None => None,
            };
            for (what, len, n) in
                [("NORMAL", normals.as_ref().map(Vec::len), 3), ("TEXCOORD_0", uvs.as_ref().map(Vec::len), 2)]
            {
                if let Some(len) = len {
                    if len / n != vertices {
                        bail!("{at}: {what} has {} elements for {vertices} positions", len / n);
                    }
                }
            }
            let indices: Vec<usize> = match prim.indices() {
                Some(a) => {
                    use ::gltf::accessor::DataType;
                    if !matches!(a.data_type(), DataType::U8 | DataType::U16 | DataType::U32) || a.normalized() {
                        bail!("{at}: indices accessor {} is not unsigned integers", a.index());
                    }
                    let raw = read_accessor(&buffers, &a, 1, "indices").map_err(|e| anyhow!("{at}: {e}"))?;
                    let mut out = Vec::with_capacity(raw.len());
                    for x in raw {
                        let i = x as usize;
                        if i >= vertices {
                            bail!("{at}: index {i} out of range ({vertices} vertices)");
                        }
                        out.push(i);
                    }
                    out
                }
                None => (0..vertices).collect(),
            };
            let corners: Vec<[usize; 3]> = match mode {
                Mode::Triangles => indices.as_chunks::<3>().0.to_vec(),
                Mode::TriangleStrip => (0..indices.len().saturating_sub(2))
                    .map(|i| {
                        if i % 2 == 0 {
                            [indices[i], indices[i + 1], indices[i + 2]]
                        } else {
                            [indices[i + 1], indices[i], indices[i + 2]]
                        }
                    })
                    .collect(),
                _ => (1..indices.len().saturating_sub(1)).map(|i| [indices[0], indices[i], indices[i + 1]]).collect(),
            };
            let mat = prim.material().index().map_or(default_material, |i| i as u32);
            let out = &outs[mat as usize];
            if out.invisible {
                cut += corners.len();
                continue;
            }
            let has_attributes = normals.is_some() || uvs.is_some();
            any_attributes |= has_attributes;
            for c in corners {
                let v = c.map(|i| {
                    world.transform_point3(DVec3::new(positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]))
                });
                let mut a = WorldAttributes::default();
                if let Some(n) = &normals {
                    let ns = c.map(|i| normal_matrix * DVec3::new(n[3 * i], n[3 * i + 1], n[3 * i + 2]));
                    let lengths = ns.map(|n| n.length());
                    if lengths.iter().all(|l| l.is_finite() && *l > 0.0) {
                        a.normals = [0, 1, 2].map(|j| ns[j] / lengths[j]);
                    }
                }
                if let Some(t) = &uvs {
                    a.uv = c.map(|i| {
                        let [u, v] = out.uv.apply([t[2 * i], t[2 * i + 1]]);
                        [u, 1.0 - v]
                    });
                }
                let (v, a) = if mirrors {
                    (
                        [v[0], v[2], v[1]],
                        WorldAttributes {
                            normals: [a.normals[0], a.normals[2], a.normals[1]],
                            uv: [a.uv[0], a.uv[2], a.uv[1]],
                        },
                    )
                } else {
                    (v, a)
                };
                for x in v {
                    if !x.is_finite() || x.abs().max_element() > MAX_COORDINATE as f64 {
                        bail!("{at}: placed vertex {x} is not finite or beyond ±{MAX_COORDINATE:e}");
                    }
                }
                triangles.push(v);
                material_of.push(mat);
                attributes.push(a);
            }
        }
    }
    if !any_attributes {
        attributes.clear();
    }
    cameras.sort_by_key(|c| c.index);
    if cut > 0 {
        warnings.push(format!("{p}: {cut} triangles cut out: their material's alpha is below its alphaCutoff"));
    }
    warnings.extend(notes);
    if triangles.is_empty() {
        bail!("{p}: no triangles in the scene");
    }
    let scene = WorldScene {
        triangles,
        material_of,
        materials: outs.iter().map(|o| o.material).collect(),
        material_names: names,
        attributes,
        textures,
        environment_map: None,
        punctual_lights: lights,
    };
    Ok(GltfScene { mesh: Mesh { scene, warnings }, cameras })
}

/// A KHR_lights_punctual light as its node places it (world coordinates; it shines along the
/// node's −Z), in the extension's units (candela for point and spot lights, lux for
/// directional ones), which are `PunctualLight`'s. `range` only limits a light for real-time
/// renderers; a physically based one ignores it, with a warning.
fn light_of(
    p: &str,
    node: usize,
    l: &::gltf::khr_lights_punctual::Light,
    world: DMat4,
    linear: DMat3,
    warnings: &mut Vec<String>,
) -> Result<PunctualLight> {
    use ::gltf::khr_lights_punctual::Kind as K;
    let label = match l.name() {
        Some(n) => format!("{p}: node {node}: light {} ({n:?})", l.index()),
        None => format!("{p}: node {node}: light {}", l.index()),
    };
    let position = world.transform_point3(DVec3::ZERO);
    let direction = linear * DVec3::NEG_Z;
    let color = Vec3::from(l.color());
    let light = match l.kind() {
        K::Directional => PunctualLight::directional(direction, color, l.intensity()),
        K::Point => PunctualLight::point(position, color, l.intensity()),
        K::Spot { inner_cone_angle, outer_cone_angle } => {
            PunctualLight::spot(position, direction, color, l.intensity(), inner_cone_angle, outer_cone_angle)
        }
    };
    light.check().map_err(|e| anyhow!("{label}: {e}"))?;
    if let Some(r) = l.range() {
        warnings.push(format!("{label}: range {r} ignored (light falls off with the inverse square only)"));
    }
    Ok(light)
}

/// Whether `path` names a glTF file (`.gltf` or `.glb`).
pub fn is_gltf(path: &Path) -> bool {
    path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).is_some_and(|e| e == "gltf" || e == "glb")
}

/// Loads a mesh file for a scene file's `[[mesh]]`: an OBJ (+ MTL) or a glTF file (its cameras
/// and lights left out).
pub fn load_any_mesh(path: &Path, files: &dyn Files) -> Result<Mesh> {
    if is_gltf(path) {
        load(path, files).map(|g| g.mesh)
    } else {
        crate::scene::obj::load_mesh(path, files)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texture_transforms_follow_the_extension() {
        // Offset, then rotation about the origin, then scale: T·R·S with R = [c s; −s c].
        let (s, c) = 0.5f64.sin_cos();
        let t = UvTransform([c * 2.0, s * 3.0, 0.25, -s * 2.0, c * 3.0, 0.5]);
        let [u, v] = t.apply([1.0, 1.0]);
        assert!((u - (2.0 * c + 3.0 * s + 0.25)).abs() < 1e-12);
        assert!((v - (-2.0 * s + 3.0 * c + 0.5)).abs() < 1e-12);
        assert_eq!(UvTransform::IDENTITY.apply([0.3, 0.7]), [0.3, 0.7]);
    }

    #[test]
    fn uris_are_percent_decoded() {
        assert_eq!(percent_decode("my%20image.png"), "my image.png");
        assert_eq!(percent_decode("100%"), "100%");
        assert_eq!(percent_decode("a%zzb"), "a%zzb");
        assert_eq!(percent_decode("é%41"), "éA");
    }

    #[test]
    fn node_transforms_are_read_in_f64() {
        let json: serde_json::Value = serde_json::from_str(
            r#"{"nodes": [{"translation": [400000.123456789, 6000000.987654321, 0.5]},
                          {"matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 5,6,7,1]},
                          {"rotation": [0, 0, 0, 0]},
                          {"translation": [1, 2]}]}"#,
        )
        .unwrap();
        let p = Path::new("t.gltf");
        let m = node_matrix(p, &json, 0).unwrap();
        assert_eq!(m.transform_point3(DVec3::ZERO), DVec3::new(400000.123456789, 6000000.987654321, 0.5));
        assert_eq!(node_matrix(p, &json, 1).unwrap().transform_point3(DVec3::ZERO), DVec3::new(5.0, 6.0, 7.0));
        assert!(node_matrix(p, &json, 2).unwrap_err().to_string().contains("zero quaternion"));
        assert!(node_matrix(p, &json, 3).unwrap_err().to_string().contains("translation needs 3 numbers"));
    }
}
