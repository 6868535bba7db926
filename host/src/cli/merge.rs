//! `kdtrace merge`: adds partial renders (`render --partial`) into one image, equal bit for bit
//! to one render of all their samples. Parts of another scene or other settings, and parts
//! that overlap or leave samples out, are refused with the files named.
use super::print_json;
use crate::files;
use crate::image::io;
use crate::render::blocks::{Fold, BLOCK_SAMPLES};
use crate::render::partial::{Header, Partial};
use crate::render::Rendered;
use crate::settings::Traversal;
use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

#[derive(Args)]
pub struct MergeArgs {
    /// Partial renders (`render --partial`) of one scene and settings whose samples, together,
    /// are 0..N with no gap or overlap, in any order.
    #[arg(required = true, value_name = "PART")]
    parts: Vec<PathBuf>,
    /// The image: PNG (sRGB) or EXR (linear).
    #[arg(long)]
    out: PathBuf,
    /// Also write each pixel's per-sample variance (linear EXR), for `compare --variance`.
    #[arg(long, value_name = "VAR.exr")]
    variance: Option<PathBuf>,
    /// Print one JSON line to stdout.
    #[arg(long)]
    json: bool,
}

/// `merge --json`.
#[derive(Serialize)]
struct MergeReport<'a> {
    out: &'a PathBuf,
    variance: &'a Option<PathBuf>,
    parts: usize,
    scene: &'a str,
    scene_hash: &'a str,
    width: u32,
    height: u32,
    spp: u32,
    zeroed_samples: u64,
    merge_s: f64,
}

pub fn run(m: MergeArgs) -> Result<ExitCode> {
    io::check_output_path(&m.out)?;
    if let Some(v) = &m.variance {
        if !io::is_exr(v) {
            bail!("{}: the variance image is linear: write it as .exr", v.display());
        }
    }
    let outputs: Vec<&Path> = std::iter::once(m.out.as_path()).chain(m.variance.as_deref()).collect();
    let inputs: Vec<&Path> = m.parts.iter().map(PathBuf::as_path).collect();
    files::check_outputs(&outputs, &inputs)?;
    let t = Instant::now();
    let headers: Vec<(&Path, Header)> =
        inputs.iter().map(|&p| Ok((p, Partial::read_header(p)?))).collect::<Result<_>>()?;
    let image = merge(&headers, Partial::read)?;
    let (first, s) = (&headers[0].1, &headers[0].1.settings);
    let pixels = image.mean();
    if io::is_exr(&m.out) {
        io::write_image(&m.out, s.width, s.height, &pixels)?;
    } else {
        io::write_image(&m.out, s.width, s.height, &io::for_display(s.aov, &pixels))?;
    }
    if let Some(v) = &m.variance {
        io::write_image(v, s.width, s.height, &image.variance())?;
    }
    let merge_s = t.elapsed().as_secs_f64();
    if m.json {
        print_json(&MergeReport {
            out: &m.out,
            variance: &m.variance,
            parts: headers.len(),
            scene: &first.scene,
            scene_hash: &first.scene_hash,
            width: s.width,
            height: s.height,
            spp: image.spp,
            zeroed_samples: image.zeroed_samples(),
            merge_s,
        })?;
    } else {
        eprintln!(
            "{}: {} parts, {}x{} at {} spp: merged in {merge_s:.3} s",
            m.out.display(),
            headers.len(),
            s.width,
            s.height,
            image.spp
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// Checks that the parts' headers are of one scene and settings and that their samples tile
/// `0..N`, then folds their nodes, read by `read` one part at a time in sample order (the fold
/// then holds a few nodes besides one part's), as one render of `0..N` does (`render::blocks`).
pub fn merge(parts: &[(&Path, Header)], read: impl Fn(&Path) -> Result<Partial>) -> Result<Rendered> {
    let Some((first_path, h0)) = parts.first() else { bail!("no part to merge") };
    for (path, h) in &parts[1..] {
        if h.scene_hash != h0.scene_hash {
            bail!(
                "{} and {} are renders of different scenes ({} hashes {}, {} hashes {}); parts must be of one \
                 scene, loaded alike (the same file, the same k-d tree)",
                first_path.display(),
                path.display(),
                h0.scene,
                h0.scene_hash,
                h.scene,
                h.scene_hash
            );
        }
        let differ = h0.settings.differences(&h.settings);
        if !differ.is_empty() {
            bail!(
                "{} and {} were rendered with different settings: {}",
                first_path.display(),
                path.display(),
                differ.join(", ")
            );
        }
    }
    // In sample order, each part must start where the previous one ended.
    let mut order: Vec<&(&Path, Header)> = parts.iter().collect();
    order.sort_by_key(|(_, h)| h.samples);
    let range = |h: &Header| format!("samples {}..{}", h.samples[0], h.samples[1]);
    let mut end = 0u32;
    let mut previous: Option<&(&Path, Header)> = None;
    for item @ (path, h) in &order {
        let [a, b] = h.samples;
        match previous {
            None if a != 0 => {
                bail!("samples 0..{a} are missing: the first part, {} ({}), starts at {a}", path.display(), range(h))
            }
            Some((prev_path, prev)) if a < end => {
                bail!("{} ({}) and {} ({}) overlap", prev_path.display(), range(prev), path.display(), range(h))
            }
            Some((prev_path, prev)) if a > end => bail!(
                "samples {end}..{a} are missing: no part holds them between {} ({}) and {} ({})",
                prev_path.display(),
                range(prev),
                path.display(),
                range(h)
            ),
            // Parts start on blocks, so a gap is found first; kept for the rule's sake.
            Some((prev_path, prev)) if !end.is_multiple_of(BLOCK_SAMPLES) => bail!(
                "{} ({}) ends inside a block of {BLOCK_SAMPLES} samples, so it must be the last part, yet {} ({}) \
                 follows",
                prev_path.display(),
                range(prev),
                path.display(),
                range(h)
            ),
            _ => {}
        }
        end = b;
        previous = Some(item);
    }
    let s = &h0.settings;
    let mut fold = Fold::new(s.width as usize * s.height as usize);
    for (path, h) in &order {
        let part = read(path)?;
        let p = &part.header;
        if p.samples != h.samples || p.settings != h.settings || p.scene_hash != h.scene_hash {
            bail!("{}: changed while being merged", path.display());
        }
        for n in part.nodes {
            fold.insert(n).with_context(|| format!("{}", path.display()))?;
        }
    }
    let (sums, spp) = fold.total(None)?.ok_or_else(|| anyhow!("the parts hold no sample"))?;
    Ok(Rendered {
        width: s.width,
        height: s.height,
        spp,
        sum: sums.sum,
        sum_sq: sums.sum_sq,
        // Partial files keep no primary hits (only `verify` reads them).
        primary: vec![shared::layout::NO_HIT; fold.pixels()],
        traversal: Traversal::Auto,
        counts: None,
    })
}
