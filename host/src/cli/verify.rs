//! `kdtrace verify`: the same samples on the CPU and the GPU, and how well they agree.
use super::args::{Device, ImageArgs};
use super::{load, print_json, run_device, settings};
use crate::render::verify::{compare, Agreement, REL_TOLERANCE};
use crate::settings::DEFAULT_SPP;
use anyhow::{bail, Result};
use clap::Args;
use serde::Serialize;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args)]
pub struct VerifyArgs {
    scene: PathBuf,
    #[command(flatten)]
    image: ImageArgs,
}

/// `verify --json`.
#[derive(Serialize)]
struct VerifyReport<'a> {
    scene: &'a PathBuf,
    cpu: &'a str,
    adapter: &'a str,
    cpu_render_s: f64,
    gpu_render_s: f64,
    spp: u32,
    width: u32,
    height: u32,
    agreement: &'a Agreement,
}

pub fn run(v: VerifyArgs) -> Result<ExitCode> {
    // One tree for both devices (the CPU's), so any difference is the devices', not the trees'.
    let mut loaded = load(&v.scene, Device::Cpu.build_settings(), v.image.camera.as_deref())?;
    let mut s = settings(&v.image, &mut loaded, &v.scene)?;
    let c = &loaded.compiled;
    if s.time_limit_s.take().is_some() {
        // Both devices must render the same samples to be compared: a budget would stop them
        // at different spp.
        if v.image.scene.time_limit_s.is_some() {
            bail!("verify renders the same samples on both devices: --time-limit does not apply (use --spp)");
        }
        if v.image.scene.spp.is_none() && loaded.settings.spp.is_none() {
            s.spp = DEFAULT_SPP;
        }
    }
    let cpu = run_device(Device::Cpu, c, &s, &v.image)?;
    let gpu = run_device(Device::Gpu, c, &s, &v.image)?;
    let a = compare(&cpu.image, &gpu.image);
    if v.image.json {
        print_json(&VerifyReport {
            scene: &v.scene,
            cpu: &cpu.adapter,
            adapter: &gpu.adapter,
            cpu_render_s: cpu.render_s,
            gpu_render_s: gpu.render_s,
            spp: s.spp,
            width: s.width,
            height: s.height,
            agreement: &a,
        })?;
    } else {
        outln!(
            "scene {} ({}x{}, {} spp, seed {}): CPU {} {:.3} s, GPU {} {:.3} s",
            v.scene.display(),
            s.width,
            s.height,
            s.spp,
            s.seed,
            cpu.adapter,
            cpu.render_s,
            gpu.adapter,
            gpu.render_s
        )?;
        outln!(
            "pixels within {REL_TOLERANCE:e} relative: {}/{} ({:.4}%), bit-identical {}; relMSE {:.3e}; \
             max relative difference {:.3e}",
            a.pixels_within,
            a.pixels,
            100.0 * a.pixel_share,
            a.bitwise_identical_pixels,
            a.relmse,
            a.max_rel_diff
        )?;
        outln!("primary hits identical: {}/{} ({:.4}%)", a.primary_matches, a.pixels, 100.0 * a.primary_share)?;
        if let Some(d) = &a.first_divergent {
            outln!("first divergent pixel ({}, {}): cpu {:?} gpu {:?}", d.x, d.y, d.cpu, d.gpu)?;
        }
        outln!("{}", if a.pass { "AGREE" } else { "DISAGREE" })?;
    }
    Ok(if a.pass { ExitCode::SUCCESS } else { ExitCode::from(1) })
}
