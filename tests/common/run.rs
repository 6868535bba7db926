//! Running the `kdtrace` binary from tests.
#![allow(dead_code)]
use std::path::Path;

/// `kdtrace export SCENE --out OUT`, which must succeed.
pub fn export(scene: &Path, out: &Path) {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_kdtrace"))
        .args(["export", scene.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "export {}: {}", scene.display(), String::from_utf8_lossy(&o.stderr));
}
