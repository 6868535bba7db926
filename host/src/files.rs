//! Input and output files.
//!
//! Inputs: every loader reads through [`read_input`] (the [`Disk`] side of the [`Files`] seam,
//! which lets fuzz targets and tests drive the OBJ → MTL → texture and scene-file → mesh chain
//! from memory). It reads regular files only, each up to a stated size: a FIFO would block
//! forever and `/dev/zero` never ends, so both are refused before they are opened, and a file that
//! grows while it is read is cut off at the cap, not read until memory runs out.
//!
//! Outputs: [`check_outputs`] runs before any work (the folder exists and takes a new file, no
//! output is an input or another output), and [`write_atomic`] writes through a temporary file in
//! the same folder that is flushed, synced and renamed over the target only when complete, so a
//! failed write (full disk, file-size limit, crash) leaves the previous file as it was.
use anyhow::{anyhow, bail, Context, Result};
use std::collections::HashMap;
use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter, Read, Write};
use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};

/// The most an OBJ, MTL or TOML scene file may hold.
pub const MAX_TEXT_BYTES: u64 = 4 << 30;
/// The most a compiled `.kdc` scene may hold.
pub const MAX_KDC_BYTES: u64 = 64 << 30;
/// The most an EXR or PFM image read by `compare` may hold (a 16384² RGB float image is 3 GiB).
pub const MAX_IMAGE_BYTES: u64 = 4 << 30;

pub trait Files {
    /// The whole file.
    fn read(&self, path: &Path) -> io::Result<Vec<u8>>;
    /// Whether a file is there (texture maps kdtrace ignores are checked, not read).
    fn exists(&self, path: &Path) -> bool;
}

/// The real file system, text inputs up to `MAX_TEXT_BYTES`.
pub struct Disk;

impl Files for Disk {
    fn read(&self, path: &Path) -> io::Result<Vec<u8>> {
        read_input(path, MAX_TEXT_BYTES)
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

/// The size of the regular file at `path` (symbolic links followed), or an error naming what
/// else it is: nothing is opened, so a FIFO cannot block.
pub fn input_size(path: &Path, cap: u64) -> io::Result<u64> {
    let meta = std::fs::metadata(path)?;
    let t = meta.file_type();
    if !t.is_file() {
        let what = if t.is_dir() {
            "a directory"
        } else if t.is_fifo() {
            "a FIFO"
        } else if t.is_char_device() || t.is_block_device() {
            "a device"
        } else if t.is_socket() {
            "a socket"
        } else {
            "something else"
        };
        return Err(io::Error::new(io::ErrorKind::InvalidInput, format!("{what}, not a regular file")));
    }
    if meta.len() > cap {
        return Err(too_big(meta.len(), cap));
    }
    Ok(meta.len())
}

fn too_big(len: u64, cap: u64) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, format!("{len} bytes, beyond the {cap} bytes this input may hold"))
}

/// Text without a leading UTF-8 byte-order mark (some editors write one; it would otherwise
/// become part of the first line's first word).
pub fn without_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes)
}

/// A whole regular file of at most `cap` bytes.
pub fn read_input(path: &Path, cap: u64) -> io::Result<Vec<u8>> {
    let len = input_size(path, cap)?;
    let mut bytes = Vec::with_capacity(len as usize);
    File::open(path)?.take(cap + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > cap {
        return Err(too_big(bytes.len() as u64, cap));
    }
    Ok(bytes)
}

/// `path` with its folder resolved (the file itself need not exist): how two names of one file
/// are recognised.
fn resolved(path: &Path) -> Result<PathBuf> {
    let name = path.file_name().ok_or_else(|| anyhow!("{}: not a file name", path.display()))?;
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let meta = std::fs::metadata(parent)
        .map_err(|e| anyhow!("{}: output folder {}: {e}", path.display(), parent.display()))?;
    if !meta.is_dir() {
        bail!("{}: {} is not a folder", path.display(), parent.display());
    }
    let folder = parent.canonicalize().with_context(|| format!("{}: output folder", path.display()))?;
    Ok(folder.join(name))
}

/// Checks, before any work, that every output can be written: its folder exists and takes a new
/// file, it is not a folder itself, and it names neither an input nor another output.
pub fn check_outputs(outputs: &[&Path], inputs: &[&Path]) -> Result<()> {
    let inputs: Vec<PathBuf> = inputs.iter().filter_map(|p| p.canonicalize().ok()).collect();
    let mut seen: Vec<(PathBuf, &Path)> = Vec::new();
    for &out in outputs {
        let full = resolved(out)?;
        if full.is_dir() {
            bail!("{}: is a folder", out.display());
        }
        if inputs.contains(&full) || full.canonicalize().is_ok_and(|c| inputs.contains(&c)) {
            bail!("{}: is also an input; write the output elsewhere", out.display());
        }
        if let Some((_, other)) = seen.iter().find(|(p, _)| *p == full) {
            bail!("{} and {} name the same file", other.display(), out.display());
        }
        // The folder takes a new file (permissions, read-only mounts): try one.
        let probe = temporary_name(&full, "probe");
        OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&probe)
            .map_err(|e| anyhow!("{}: cannot write in its folder: {e}", out.display()))?;
        let _ = std::fs::remove_file(&probe);
        seen.push((full, out));
    }
    Ok(())
}

/// A name beside `target` for a file on its way there.
fn temporary_name(target: &Path, what: &str) -> PathBuf {
    let name = target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    target.with_file_name(format!(".{name}.{what}-{}.kdtrace", std::process::id()))
}

/// Writes `path` through a temporary file in the same folder: `write` fills it, then it is
/// flushed, synced and renamed over `path`. On any error the temporary file is removed and a
/// previous `path` is left byte for byte as it was; every write error is an error.
pub fn write_atomic(path: &Path, write: impl FnOnce(&mut BufWriter<File>) -> Result<()>) -> Result<()> {
    let full = resolved(path)?;
    let tmp = temporary_name(&full, "partial");
    let result = (|| -> Result<()> {
        let file = OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        std::fs::rename(&tmp, &full)?;
        Ok(())
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(e.context(format!("{}: cannot write", path.display())));
    }
    Ok(())
}

/// `bytes` written to `path` by `write_atomic`.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |w| Ok(w.write_all(bytes)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("kdtrace-files-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn only_regular_files_are_read_and_only_up_to_the_cap() {
        let d = dir("inputs");
        let f = d.join("a.obj");
        std::fs::write(&f, b"v 0 0 0\n").unwrap();
        assert_eq!(read_input(&f, 100).unwrap(), b"v 0 0 0\n");
        let e = read_input(&f, 4).unwrap_err().to_string();
        assert!(e.contains("beyond the 4 bytes"), "{e}");
        let e = read_input(&d, 100).unwrap_err().to_string();
        assert!(e.contains("a directory"), "{e}");
        let e = read_input(Path::new("/dev/zero"), 100).unwrap_err().to_string();
        assert!(e.contains("a device"), "{e}");
        let fifo = d.join("fifo");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        let e = read_input(&fifo, 100).unwrap_err().to_string();
        assert!(e.contains("a FIFO"), "{e}");
    }

    #[test]
    fn a_failed_write_leaves_the_previous_file_and_no_temporary() {
        let d = dir("atomic");
        let f = d.join("out.png");
        std::fs::write(&f, b"previous").unwrap();
        let e = write_atomic(&f, |w| {
            w.write_all(b"half of the new")?;
            bail!("disk full")
        })
        .unwrap_err();
        assert!(format!("{e:#}").contains("disk full"), "{e:#}");
        assert_eq!(std::fs::read(&f).unwrap(), b"previous");
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1, "a temporary file was left behind");
        write_bytes(&f, b"new").unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), b"new");
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
    }

    #[test]
    fn outputs_are_checked_before_any_work() {
        let d = dir("outputs");
        let input = d.join("scene.obj");
        std::fs::write(&input, b"").unwrap();
        let (a, b) = (d.join("a.png"), d.join("b.exr"));
        check_outputs(&[&a, &b], &[&input]).unwrap();
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1, "the probe was left behind");
        let e = check_outputs(&[&a, &d.join(".").join("a.png")], &[]).unwrap_err().to_string();
        assert!(e.contains("name the same file"), "{e}");
        let e = check_outputs(&[&input], &[&input]).unwrap_err().to_string();
        assert!(e.contains("is also an input"), "{e}");
        let e = check_outputs(&[&d.join("missing/a.png")], &[]).unwrap_err().to_string();
        assert!(e.contains("output folder"), "{e}");
        let e = check_outputs(&[&d], &[]).unwrap_err().to_string();
        assert!(e.contains("is a folder"), "{e}");
    }
}
