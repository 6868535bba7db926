//! Where the loaders read input files from: the disk for the CLI, memory for the fuzz targets
//! and tests. Loading through this one seam lets a fuzzer drive the whole OBJ → MTL → texture and
//! scene-file → mesh chain without touching the file system.
use std::collections::HashMap;
use std::io;
use std::path::{Path, PathBuf};

pub trait Files {
    /// The whole file.
    fn read(&self, path: &Path) -> io::Result<Vec<u8>>;
    /// Whether a file is there (textures are checked, not read: nothing samples them yet).
    fn exists(&self, path: &Path) -> bool;
}

/// The real file system.
pub struct Disk;

impl Files for Disk {
    fn read(&self, path: &Path) -> io::Result<Vec<u8>> {
        std::fs::read(path)
    }
    fn exists(&self, path: &Path) -> bool {
        path.is_file()
    }
}

/// Files held in memory, keyed by the exact path the loader asks for.
#[derive(Default)]
pub struct InMemory(pub HashMap<PathBuf, Vec<u8>>);

impl InMemory {
    pub fn with(mut self, path: impl Into<PathBuf>, bytes: impl Into<Vec<u8>>) -> Self {
        self.0.insert(path.into(), bytes.into());
        self
    }
}

impl Files for InMemory {
    fn read(&self, path: &Path) -> io::Result<Vec<u8>> {
        self.0.get(path).cloned().ok_or_else(|| io::Error::new(io::ErrorKind::NotFound, "not in memory"))
    }
    fn exists(&self, path: &Path) -> bool {
        self.0.contains_key(path)
    }
}
