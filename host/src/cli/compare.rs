//! `kdtrace compare`: a linear image against a reference, and optionally a per-pixel test.
use super::print_json;
use crate::image::io::read_linear_image;
use crate::image::metrics::{errors, pixel_test, Errors, LinearImage, PixelStats, PixelTest};
use anyhow::{bail, Result};
use clap::Args;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Args)]
pub struct CompareArgs {
    /// Reference image (.exr, .hdr or .pfm).
    reference: PathBuf,
    /// Test image (.exr, .hdr or .pfm), same size.
    test: PathBuf,
    /// The test image's per-sample variance (`render --variance`): adds a per-pixel test of the
    /// test image against the reference (Šidák-corrected, α = 0.01). Needs --spp.
    #[arg(long, requires = "spp")]
    variance: Option<PathBuf>,
    /// Samples per pixel of the test image (at least 2: a per-pixel test needs a variance).
    #[arg(long)]
    spp: Option<u64>,
    /// Print one JSON line instead of text.
    #[arg(long)]
    json: bool,
}

/// `compare --json`.
#[derive(Serialize)]
struct CompareReport<'a> {
    #[serde(flatten)]
    errors: &'a Errors,
    reference: &'a PathBuf,
    test: &'a PathBuf,
    pixel_test: Option<&'a PixelTest>,
}

fn read(p: &Path) -> Result<LinearImage> {
    let (w, h, px) = read_linear_image(p)?;
    LinearImage::new(w, h, px)
}

/// Fails naming both files when `a` and `b` differ in size.
fn same_size(a: &LinearImage, a_path: &Path, b: &LinearImage, b_path: &Path) -> Result<()> {
    if (a.width, a.height) != (b.width, b.height) {
        bail!(
            "{} is {}x{} but {} is {}x{}: images of different sizes",
            a_path.display(),
            a.width,
            a.height,
            b_path.display(),
            b.width,
            b.height
        );
    }
    Ok(())
}

pub fn run(a: CompareArgs) -> Result<ExitCode> {
    let (r, t) = (read(&a.reference)?, read(&a.test)?);
    same_size(&r, &a.reference, &t, &a.test)?;
    let e = errors(&r, &t)?;
    let test = match (&a.variance, a.spp) {
        (Some(_), Some(spp)) if spp < 2 => {
            bail!("--spp {spp}: a per-pixel test needs at least 2 samples per pixel")
        }
        (Some(v), Some(spp)) => {
            let variance = read(v)?;
            same_size(&variance, v, &t, &a.test)?;
            let count = vec![spp; t.pixels.len()];
            Some(pixel_test(&r, &PixelStats { mean: t.clone(), variance, count }, 0.01)?)
        }
        _ => None,
    };
    if a.json {
        print_json(&CompareReport { errors: &e, reference: &a.reference, test: &a.test, pixel_test: test.as_ref() })?;
    } else {
        if let Some(p) = &test {
            outln!(
                "per-pixel test (Šidák, α = 0.01): {} of {} channel values rejected at {:.3e}, smallest p {:.3e}{}: {}",
                p.rejected,
                p.tests,
                p.per_test_alpha,
                p.min_p,
                p.worst.map_or(String::new(), |(x, y, k)| format!(" at ({x}, {y}) channel {k}")),
                if p.pass { "consistent" } else { "INCONSISTENT" }
            )?;
        }
        outln!(
            "{} vs reference {} ({}x{}): RMSE {:.6e}, relMSE {:.6e}, MAE {:.6e}, FLIP {:.6} ({} ppd), mean ratio \
             {:.6}; NaN/Inf: reference {}/{}, test {}/{}",
            a.test.display(),
            a.reference.display(),
            e.width,
            e.height,
            e.rmse,
            e.relmse,
            e.mae,
            e.flip,
            e.flip_ppd,
            e.mean_ratio,
            e.reference_nonfinite.nan,
            e.reference_nonfinite.inf,
            e.test_nonfinite.nan,
            e.test_nonfinite.inf
        )?;
    }
    Ok(if test.is_some_and(|p| !p.pass) { ExitCode::from(1) } else { ExitCode::SUCCESS })
}
