//! Where the tests find their files: the repository's own folders only, never `../shared`, so a
//! clone of the repository passes its tests alone.
#![allow(dead_code)]
use std::path::PathBuf;

/// A path relative to the repository's root.
pub fn repo(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join(rel)
}

/// A mesh copied into `tests/data/meshes` (see its README for origins and licences).
pub fn mesh(rel: &str) -> PathBuf {
    let p = repo("tests/data/meshes").join(rel);
    assert!(p.exists(), "{} is missing from the repository's test data", p.display());
    p
}
