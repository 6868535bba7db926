//! TOML scene files: parsing, checking, and resolving against an in-memory mesh `mesh.obj`
//! (two MTL materials `a` and `b`, faces with and without `usemtl`), then the render settings.
#![no_main]
use kdtrace::{files::InMemory, scene::file};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

const OBJ: &str =
    "mtllib mesh.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nusemtl a\nf 1 2 4\nusemtl b\nf 1 3 4\n";
const MTL: &str = "newmtl a\nKd 0.5 0.5 0.5\nnewmtl b\nKd 0 0 0\nKe 1 1 1\n";

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let path = Path::new("fuzz/scene.toml");
    let Ok(file) = file::parse(path, text) else { return };
    let files = InMemory::default().with("fuzz/mesh.obj", OBJ).with("fuzz/mesh.mtl", MTL);
    if let Ok(r) = file::resolve(path, text, &file, &files) {
        if let Ok((scene, origin)) = r.scene.into_local() {
            let _ = r.settings.resolve(scene.bounds_min.as_dvec3() + origin, scene.bounds_max.as_dvec3() + origin);
        }
        // What export writes must parse again.
        if let Ok(f) = file::with_settings(file, &r.settings) {
            let written = file::to_toml(&f, "fuzz").expect("a checked scene serialises");
            file::parse(path, &written).expect("export output parses");
        }
    }
});
