//! The memory a render needs, checked before anything is allocated: a 16384² image takes
//! gigabytes of accumulation buffers, and an allocation the system cannot back ends the process
//! by signal (or the out-of-memory killer) after the scene was loaded and built, with nothing
//! said. Counted per pixel: the CPU path's sums of radiance and of its squares and the primary
//! hit (36 bytes), the second block's sums of a pass of two blocks (32 bytes), the mean and
//! variance images and the 8-bit output (27 bytes); a GPU adds the
//! device buffers and their read-back copies (72 bytes; on lavapipe device memory is host memory).
use anyhow::{bail, Result};

/// Bytes per pixel of a CPU render, and what a GPU render adds.
const CPU_BYTES_PER_PIXEL: u64 = 96;
const GPU_EXTRA_BYTES_PER_PIXEL: u64 = 72;

/// The memory this process may still use: the least of the system's available memory and the
/// address-space limit (`ulimit -v`), where the system reports them (Linux's /proc).
pub fn available() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok();
    let mem = meminfo.as_deref().and_then(|m| {
        let line = m.lines().find(|l| l.starts_with("MemAvailable:"))?;
        Some(line.split_whitespace().nth(1)?.parse::<u64>().ok()? * 1024)
    });
    let limits = std::fs::read_to_string("/proc/self/limits").ok();
    let address_space = limits.as_deref().and_then(|l| {
        let line = l.lines().find(|l| l.starts_with("Max address space"))?;
        line.split_whitespace().nth(3)?.parse::<u64>().ok()
    });
    match (mem, address_space) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// Bytes a `width` × `height` render needs on the CPU, or on a GPU.
pub fn needed(width: u32, height: u32, gpu: bool) -> u64 {
    let per_pixel = CPU_BYTES_PER_PIXEL + if gpu { GPU_EXTRA_BYTES_PER_PIXEL } else { 0 };
    width as u64 * height as u64 * per_pixel
}

/// An error, with the size needed, when the image's buffers would not fit.
pub fn check(width: u32, height: u32, gpu: bool) -> Result<()> {
    let need = needed(width, height, gpu);
    if let Some(free) = available() {
        if need > free {
            let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
            bail!(
                "a {width}x{height} image needs about {:.1} GiB for its buffers{}, but only {:.1} GiB are available",
                gib(need),
                if gpu { " on a GPU" } else { "" },
                gib(free)
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_largest_image_needs_gigabytes_and_a_small_one_fits() {
        assert_eq!(needed(16384, 16384, false), 16384 * 16384 * 96);
        assert!(needed(16384, 16384, true) > needed(16384, 16384, false));
        check(64, 64, true).unwrap();
        assert!(available().is_some_and(|a| a > 0), "Linux reports the memory available");
    }
}
