//! One client's render: passes of whole samples through the device's progressive renderer
//! (`render::progressive`), one pass at a time over all clients (`State::passes`), a PNG frame
//! after each. The frames go out through a watch channel, which holds the newest only: a slow
//! client skips frames instead of queueing them.
use super::protocol::Progress;
use super::{within_folder, State};
use crate::cli::Device;
use crate::image::io;
use crate::render::progressive::Progressive;
use crate::settings::RenderSettings;
use anyhow::{anyhow, Result};
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Instant;
use tokio::sync::watch;

/// Each pass is sized to take about this long, so that clients take turns often and a camera
/// move is answered quickly.
pub const PASS_SECONDS: f64 = 0.1;

/// The newest state of a render.
#[derive(Clone, Default)]
pub enum Update {
    #[default]
    Started,
    Frame(Arc<Frame>),
    Failed(String),
}

pub struct Frame {
    pub progress: Progress,
    pub png: Vec<u8>,
    /// The render's last frame: all its samples are in, or it was stopped.
    pub last: bool,
}

/// A render under way; dropping it does not stop it, `stop` does.
pub struct Job {
    cancel: watch::Sender<bool>,
}

impl Job {
    /// Stops the render after its current pass; one waiting for its turn leaves the queue now.
    pub fn stop(&self) {
        self.cancel.send_replace(true);
    }
}

/// What to render.
pub struct Spec {
    pub scene: usize,
    pub settings: RenderSettings,
    pub device: Device,
}

/// Starts a render on a blocking thread; its frames arrive on the returned receiver.
pub fn start(state: Arc<State>, spec: Spec) -> (Job, watch::Receiver<Update>) {
    let (tx, rx) = watch::channel(Update::Started);
    let (cancel, flag) = watch::channel(false);
    let runtime = tokio::runtime::Handle::current();
    state.renders.fetch_add(1, Ordering::SeqCst);
    tokio::task::spawn_blocking(move || {
        let _running = Running(&state);
        if let Err(e) = render(&state, &spec, &flag, &tx, &runtime) {
            // Nobody may be listening any more: the client left.
            let _ = tx.send(Update::Failed(format!("{e:#}")));
        }
    });
    (Job { cancel }, rx)
}

/// Counts a render in `State::renders` until its thread ends.
struct Running<'a>(&'a State);

impl Drop for Running<'_> {
    fn drop(&mut self) {
        self.0.renders.fetch_sub(1, Ordering::SeqCst);
    }
}

fn render(
    state: &State,
    spec: &Spec,
    cancel: &watch::Receiver<bool>,
    tx: &watch::Sender<Update>,
    runtime: &tokio::runtime::Handle,
) -> Result<()> {
    let s = &spec.settings;
    let entry = &state.scenes[spec.scene];
    let loaded = entry.loaded(spec.device).map_err(|e| anyhow!(within_folder(&format!("{e:#}"), &entry.path)))?;
    let c = &loaded.compiled;
    let mut renderer: Box<dyn Progressive + '_> = match spec.device {
        Device::Cpu => Box::new(crate::render::cpu::progressive(c, s)?),
        Device::Gpu => Box::new(state.gpu()?.progressive(c, s)?),
    };
    let device = renderer.device();
    let clock = Instant::now();
    let mut render_s = 0.0;
    let mut done = 0u32;
    let mut count = 1u32;
    while done < s.spp {
        count = count.min(s.spp - done);
        let pass_s = {
            // Wait for this client's turn, unless the render is stopped or its client leaves
            // meanwhile; the permit is given back when the pass ends.
            let mut stopped = cancel.clone();
            let turn = runtime.block_on(async {
                tokio::select! {
                    turn = state.passes.acquire() => Some(turn),
                    _ = stopped.wait_for(|&stop| stop) => None,
                    _ = tx.closed() => None,
                }
            });
            let Some(Ok(_turn)) = turn else { return Ok(()) };
            let t = Instant::now();
            renderer.pass(done, count)?;
            t.elapsed().as_secs_f64()
        };
        done += count;
        render_s += pass_s;
        let image = renderer.image()?;
        let shown = io::for_display(s.aov, &image.mean());
        let png = io::encode_png(s.width, s.height, &shown)?;
        let last = done == s.spp;
        let progress = Progress {
            spp: done,
            target: s.spp,
            samples_per_s: s.width as f64 * s.height as f64 * done as f64 / render_s.max(1e-9),
            elapsed_s: clock.elapsed().as_secs_f64(),
            scene: spec.scene,
            width: s.width,
            height: s.height,
            device: device.clone(),
        };
        if tx.send(Update::Frame(Arc::new(Frame { progress, png, last }))).is_err() {
            return Ok(());
        }
        // The next pass from this one's speed: about `PASS_SECONDS`, at most twice as many
        // samples as this one.
        let per_sample = pass_s / count as f64;
        let fit = (PASS_SECONDS / per_sample.max(1e-9)).floor().clamp(1.0, 2.0 * count as f64);
        count = fit as u32;
    }
    Ok(())
}
