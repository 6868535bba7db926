//! Every device of one machine at once (`render --device all` or a list): one thread per device,
//! each taking the next run of sample blocks (`blocks`) from a shared counter, as many as it
//! renders in about `RUN_SECONDS` by its measured speed (a fast GPU takes more, the CPU helps).
//! Each block's sums are added from zero on its device and go into one fold, which keeps blocks
//! that arrive early until their siblings come: the image is the one a single device renders of
//! the same samples, bit for bit where the devices compute the same block sums (the CPU and
//! lavapipe do).
use crate::render::blocks::{block_of, Fold, NodeId, Sums, BLOCK_SAMPLES};
use crate::render::progressive::{block_sums, RunningSums};
use crate::render::{cpu, gpu::Gpu, Compiled};
use crate::settings::RenderSettings;
use anyhow::{anyhow, bail, Result};
use serde::Serialize;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Mutex};
use std::time::Instant;

/// A device takes runs of blocks that it renders in about this long: long enough that taking a
/// run costs nothing, short enough that the devices finish close together.
const RUN_SECONDS: f64 = 0.5;

/// One device of a list.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unit {
    Cpu,
    /// Adapter `i` of `gpu::adapters()`, or (`None`) the one `--adapter` names, else the first.
    Gpu(Option<usize>),
}

impl Unit {
    /// Parses `all` or a list such as `cpu,gpu:0,gpu:1` (`gpu` alone: `--adapter`'s, else the
    /// first adapter).
    pub fn parse_list(spec: &str) -> Result<Vec<Unit>> {
        if spec == "all" {
            let gpus = crate::render::gpu::adapters().len();
            return Ok(std::iter::once(Unit::Cpu).chain((0..gpus).map(|i| Unit::Gpu(Some(i)))).collect());
        }
        let mut units = Vec::new();
        for part in spec.split(',').map(str::trim) {
            let unit = match part {
                "cpu" => Unit::Cpu,
                "gpu" => Unit::Gpu(None),
                _ => match part.strip_prefix("gpu:").map(str::parse::<usize>) {
                    Some(Ok(i)) => Unit::Gpu(Some(i)),
                    _ => bail!("--device {spec}: {part:?} is none of cpu, gpu, gpu:N (N from `kdtrace adapters`), all"),
                },
            };
            if units.contains(&unit) {
                bail!("--device {spec}: {part} is listed twice");
            }
            units.push(unit);
        }
        Ok(units)
    }
}

/// What one device rendered.
#[derive(Clone, Debug, Serialize)]
pub struct Share {
    pub device: String,
    /// Blocks of `BLOCK_SAMPLES` samples of every pixel it rendered.
    pub blocks: u32,
    /// Samples per pixel it rendered.
    pub samples: u32,
    /// Its part of all samples, 0 to 1.
    pub share: f64,
    /// Its speed, in samples (paths from a pixel) per second of its own rendering.
    pub samples_per_s: f64,
    #[serde(skip)]
    seconds: f64,
}

/// The result: the fold of every block rendered, the primary hits (from the device that
/// rendered block 0, if any did) and each device's share.
pub struct Outcome {
    pub fold: Fold,
    pub primary: Option<Vec<u32>>,
    pub shares: Vec<Share>,
    /// Seconds from the devices' start (adapters open and pipelines compiled) to the last block.
    pub render_s: f64,
}

/// A block done, or a device's failure, sent to the thread that folds.
enum Message {
    Block { device: usize, id: NodeId, sums: Sums, primary: Option<Vec<u32>>, seconds: f64 },
    Failed(anyhow::Error),
}

/// Renders samples `samples[0]..samples[1]` (the start a multiple of `BLOCK_SAMPLES`) of every
/// pixel on `units` at once; `progress` is called after each block with the shares so far.
pub fn render(
    c: &Compiled,
    s: &RenderSettings,
    units: &[Unit],
    adapter: Option<&str>,
    samples: [u32; 2],
    progress: &dyn Fn(&[Share]),
) -> Result<Outcome> {
    s.check()?;
    let [a, b] = samples;
    if !a.is_multiple_of(BLOCK_SAMPLES) || a >= b {
        bail!("samples {a}..{b}: several devices render whole blocks from a block's start");
    }
    if units.is_empty() {
        bail!("no device to render with");
    }
    // The adapters open first, so that a missing one fails before any work.
    let gpus: Vec<Option<Gpu>> = units
        .iter()
        .map(|u| match *u {
            Unit::Cpu => Ok(None),
            Unit::Gpu(Some(i)) => Gpu::open_index(i).map(Some),
            Unit::Gpu(None) => Gpu::open(adapter).map(Some),
        })
        .collect::<Result<_>>()?;
    for g in gpus.iter().flatten() {
        g.prepare(c, s)?;
    }
    // The CPU renders with a thread fewer per GPU: each GPU's thread records, submits and
    // waits for its dispatches, and a CPU busy on every core would leave it waiting.
    let gpu_count = gpus.iter().flatten().count();
    let cpu_threads = rayon::current_num_threads().saturating_sub(gpu_count).max(1);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(cpu_threads).build()?;
    let pixels = s.width as usize * s.height as usize;
    let mut shares: Vec<Share> = gpus
        .iter()
        .map(|g| Share {
            device: g
                .as_ref()
                .map_or_else(|| crate::render::cpu::adapter_name(cpu_threads), |g| g.adapter.name.clone()),
            blocks: 0,
            samples: 0,
            share: 0.0,
            samples_per_s: 0.0,
            seconds: 0.0,
        })
        .collect();
    let (first, end) = (block_of(a), block_of(b - 1) + 1);
    let workers = units.len() as u32;
    // Each device's first block is its own (block `first + i` for device `i`), so every device
    // renders at least one when there are enough and measures its speed on it; the rest go in
    // runs from a shared counter.
    let next = Mutex::new((first + workers).min(end));
    let stop = AtomicBool::new(false);
    let (tx, rx) = mpsc::channel::<Message>();
    let mut fold = Fold::new(pixels);
    let mut primary = None;
    let mut failure = None;
    let clock = Instant::now();
    std::thread::scope(|scope| {
        for (device, gpu) in gpus.iter().enumerate() {
            let (tx, next, stop, pool, name) = (tx.clone(), &next, &stop, &pool, shares[device].device.clone());
            scope.spawn(move || {
                let work = || -> Result<()> {
                    let mut dev: Box<dyn RunningSums> = match gpu {
                        None => Box::new(cpu::CpuSums::new(c, s)?),
                        Some(g) => Box::new(g.sums(c, s)?),
                    };
                    let own = (first + device as u32).min(end);
                    let mut run = own..(own + 1).min(end);
                    let mut per_block: Option<f64> = None;
                    while !run.is_empty() && !stop.load(Ordering::Relaxed) {
                        let mut k = run.start;
                        while k < run.end {
                            let t = Instant::now();
                            let from = k * BLOCK_SAMPLES;
                            // Two whole blocks at once where the run holds them (the CPU fills
                            // its sixteen lanes from both; `RunningSums::add_two_blocks`).
                            let blocks: Vec<(u32, Sums)> = if k + 1 < run.end && from + 2 * BLOCK_SAMPLES <= b {
                                let [x, y] = dev.add_two_blocks(from)?;
                                vec![(BLOCK_SAMPLES, x), (BLOCK_SAMPLES, y)]
                            } else {
                                let count = BLOCK_SAMPLES.min(b - from);
                                vec![(count, block_sums(dev.as_mut(), from, count)?)]
                            };
                            let mut primary = if from == 0 { Some(dev.primary()?) } else { None };
                            let samples = blocks.iter().map(|b| b.0).sum::<u32>();
                            let seconds = t.elapsed().as_secs_f64();
                            // Per whole block: a short last block would make the device look fast.
                            per_block = Some(seconds * BLOCK_SAMPLES as f64 / samples as f64);
                            for (count, sums) in blocks {
                                let id = NodeId::block(k, count);
                                let seconds = seconds * count as f64 / samples as f64;
                                if tx
                                    .send(Message::Block { device, id, sums, primary: primary.take(), seconds })
                                    .is_err()
                                {
                                    return Ok(());
                                }
                                k += 1;
                            }
                        }
                        let mut k = next.lock().map_err(|_| anyhow!("another device failed"))?;
                        let left = end - *k;
                        // The run this device renders in about `RUN_SECONDS`, at most its share
                        // of what is left, so that no device holds the last blocks long.
                        let fit = per_block.map_or(1.0, |t| (RUN_SECONDS / t.max(1e-9)).floor());
                        let n = (fit as u32).clamp(1, (left / workers).max(1)).min(left);
                        run = *k..*k + n;
                        *k += n;
                    }
                    Ok(())
                };
                // Only the CPU's work runs in its pool: a GPU's thread would hold one of its threads.
                let result = if gpu.is_none() { pool.install(work) } else { work() };
                if let Err(e) = result {
                    stop.store(true, Ordering::Relaxed);
                    let _ = tx.send(Message::Failed(e.context(name)));
                }
            });
        }
        drop(tx);
        for m in rx {
            match m {
                Message::Block { device, id, sums, primary: p, seconds } => {
                    if let Err(e) = fold.insert(crate::render::blocks::Node { id, sums }) {
                        stop.store(true, Ordering::Relaxed);
                        failure.get_or_insert(e);
                        continue;
                    }
                    if primary.is_none() {
                        primary = p;
                    }
                    let sh = &mut shares[device];
                    sh.blocks += 1;
                    sh.samples += id.samples;
                    sh.seconds += seconds;
                    let total: u32 = shares.iter().map(|s| s.samples).sum();
                    for sh in shares.iter_mut() {
                        sh.share = sh.samples as f64 / total as f64;
                        sh.samples_per_s = pixels as f64 * sh.samples as f64 / sh.seconds.max(1e-9);
                    }
                    progress(&shares);
                }
                Message::Failed(e) => {
                    failure.get_or_insert(e);
                }
            }
        }
    });
    if let Some(e) = failure {
        return Err(e);
    }
    Ok(Outcome { fold, primary, shares, render_s: clock.elapsed().as_secs_f64() })
}
