//! `kdtrace pixel`: one sample of one pixel replayed on the CPU through the renderer's own
//! integrator (`debug::replay`), its path printed as one line of JSON (`debug::PathRecord`).
use super::args::{Device, ImageArgs};
use super::{load, print_json, settings};
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args)]
pub struct PixelArgs {
    scene: PathBuf,
    /// The pixel's column, 0 at the left.
    #[arg(long)]
    x: u32,
    /// The pixel's row, 0 at the top.
    #[arg(long)]
    y: u32,
    /// The sample to replay: sample 0 is what `render --spp 1` adds to the pixel, sample S what a
    /// render's S-th sample adds.
    #[arg(long, default_value_t = 0)]
    sample: u32,
    #[command(flatten)]
    image: ImageArgs,
}

pub fn run(a: PixelArgs) -> Result<ExitCode> {
    // The tree the CPU renders with, so the replay visits the nodes a CPU render does.
    let mut loaded = load(&a.scene, Device::Cpu.build_settings(), a.image.camera.as_deref())?;
    let s = settings(&a.image, &mut loaded, &a.scene)?;
    let record = crate::debug::replay(&loaded.compiled, &s, a.x, a.y, a.sample)?;
    print_json(&record)?;
    Ok(ExitCode::SUCCESS)
}
