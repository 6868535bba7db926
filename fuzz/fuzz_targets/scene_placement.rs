//! The scene file's placement path: a mesh placed by arbitrary scale, rotation and translation
//! (f64, as written), moved to its local frame, rounded, built into a k-d tree and rendered (4x4
//! pixels, 1 spp, CPU) with a camera at arbitrary world coordinates. The input's bytes are the
//! f64 values, so the fuzzer reaches every exponent rather than the few a TOML text mutation
//! finds. Every step either succeeds or refuses with an error; none may panic.
#![no_main]
use kdtrace::{compile, files::InMemory, scene::file};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

const OBJ: &str = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nusemtl lamp\nf 1 3 4\nf 2 4 3\n";
const MTL: &str = "newmtl lamp\nKe 1 1 1\n";

fuzz_target!(|data: &[u8]| {
    let mut values = data.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap()));
    let mut next = || values.next().unwrap_or(0.0);
    let mut v3 = || format!("[{:?}, {:?}, {:?}]", next(), next(), next());
    let (scale, rotate, translate, eye, target) = (v3(), v3(), v3(), v3(), v3());
    let text = format!(
        "[camera]\nwidth = 4\nheight = 4\neye = {eye}\ntarget = {target}\n[render]\nspp = 1\nbounces = 1\n\
         [[mesh]]\nfile = \"m.obj\"\nscale = {scale}\nrotate = {rotate}\ntranslate = {translate}\n"
    );
    let path = Path::new("fuzz/scene.toml");
    let Ok(parsed) = file::parse(path, &text) else { return };
    let files = InMemory::default().with("fuzz/m.obj", OBJ).with("fuzz/m.mtl", MTL);
    let Ok(r) = file::resolve(path, &text, &parsed, &files) else { return };
    let Ok((scene, origin)) = r.scene.into_local() else { return };
    if scene.triangles.is_empty() {
        return;
    }
    let mut c = compile(scene, kdtrace::kdbuild::BuildSettings::default());
    c.origin = origin;
    let (lo, hi) = c.world_bounds();
    if let Ok(s) = r.settings.resolve(lo, hi) {
        let _ = kdtrace::render::cpu::render(&c, &s, &|_, _| {});
    }
});
