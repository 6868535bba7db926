//! OBJ + MTL loading: the input is an OBJ file, optionally followed by a NUL byte and the MTL
//! library `scene.mtl` it may name (a texture `tex.png` exists beside it). Whatever loads must
//! also assemble into a scene and get a k-d tree.
#![no_main]
use kdtrace::{compile, files::InMemory, kdbuild, scene::obj};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let (obj_bytes, mtl_bytes) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[][..]),
    };
    let files = InMemory::default().with("fuzz/scene.mtl", mtl_bytes).with("fuzz/tex.png", b"png".to_vec());
    if let Ok(mesh) = obj::parse_mesh(Path::new("fuzz/scene.obj"), obj_bytes, &files) {
        if let Ok((s, _origin)) = mesh.scene.into_local() {
            let c = compile(s, kdbuild::BuildSettings::default());
            assert!(!c.tree.nodes.is_empty());
        }
    }
});
