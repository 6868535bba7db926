//! `kdtrace serve`: the web UI and the remote debugger. An HTTP server (axum on tokio) serves one
//! page whose HTML, JS and CSS are compiled into the binary (`page`), and a websocket (`/ws`,
//! `protocol`) over which each client renders progressively (`job`: passes of whole samples, a
//! PNG frame after each, the newest only) and replays single samples of single pixels on the CPU
//! through the integrator's recording hook (`crate::debug`).
//!
//! Sharing the machine: one pass runs at a time for all clients, taken in turn (a FIFO
//! semaphore), each pass sized to about `job::PASS_SECONDS`; a client has at most one render and
//! `session::MAX_PENDING_PIXELS` replays in flight; images are limited to `MAX_PIXELS`, messages
//! to `protocol::MAX_MESSAGE_BYTES` and clients to `--max-clients`, which bounds memory.
mod job;
mod page;
pub mod protocol;
mod session;

use crate::cli::Device;
use crate::kdbuild::BuildSettings;
use crate::render::gpu::Gpu;
use crate::settings::{MAX_BOUNCES, MAX_SPP};
use crate::Loaded;
use anyhow::{anyhow, Context, Result};
use axum::extract::ws::WebSocketUpgrade;
use axum::extract::State as AxumState;
use axum::http::header;
use axum::response::IntoResponse;
use axum::routing::get;
use axum::Router;
use protocol::{CameraInfo, Hello, Limits, SceneInfo};
use std::io::Write;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, OnceLock};
use tokio::sync::Semaphore;

/// The most pixels a client's image may have: with the sums, squares and ids a render keeps
/// (36 bytes a pixel) about 75 MB per client.
pub const MAX_PIXELS: u64 = 1 << 21;
/// Websocket messages above this close the connection (the transport's limit); between
/// `protocol::MAX_MESSAGE_BYTES` and this they get an `error` reply.
const TRANSPORT_MAX_BYTES: usize = 1 << 20;

/// What `kdtrace serve` was asked for.
pub struct Options {
    pub scenes: Vec<PathBuf>,
    pub bind: SocketAddr,
    pub device: Device,
    pub adapter: Option<String>,
    pub max_clients: usize,
}

/// One scene the page can choose: loaded with the CPU's tree (renders on the CPU and every
/// replay), and with the GPU's tree when a GPU render first asks for it.
pub(crate) struct SceneEntry {
    pub path: PathBuf,
    pub cpu: Loaded,
    pub gpu: OnceLock<Result<Arc<Loaded>, String>>,
    pub info: SceneInfo,
}

impl SceneEntry {
    /// The scene loaded for `device`'s traversal.
    pub fn loaded(&self, device: Device) -> Result<&Loaded> {
        match device {
            Device::Cpu => Ok(&self.cpu),
            Device::Gpu => {
                let g = self.gpu.get_or_init(|| {
                    crate::load(&self.path, BuildSettings::for_gpu()).map(Arc::new).map_err(|e| format!("{e:#}"))
                });
                g.as_deref().map_err(|e| anyhow!("{e}"))
            }
        }
    }
}

/// What every connection shares.
pub(crate) struct State {
    pub scenes: Vec<SceneEntry>,
    pub hello: Hello,
    pub adapter: Option<String>,
    gpu: OnceLock<Result<Gpu, String>>,
    /// One pass at a time over all clients, in turn (tokio's semaphore is fair: first come,
    /// first served).
    pub passes: Semaphore,
    pub clients: AtomicUsize,
    pub max_clients: usize,
    /// Renders whose thread is still running (stopped ones end after their current pass).
    pub renders: AtomicUsize,
}

impl State {
    /// The GPU, opened on first use.
    pub fn gpu(&self) -> Result<&Gpu> {
        self.gpu
            .get_or_init(|| Gpu::open(self.adapter.as_deref()).map_err(|e| format!("{e:#}")))
            .as_ref()
            .map_err(|e| anyhow!("{e}"))
    }
}

/// Loads the scenes, binds and serves until the process is stopped. Prints
/// `listening on http://ADDR/` on stdout once it accepts connections.
pub fn run(o: Options) -> Result<()> {
    if !o.bind.ip().is_loopback() {
        eprintln!(
            "warning: serving on {} — not a loopback address: anyone who can reach it can render and read its \
             scenes",
            o.bind
        );
    }
    let mut scenes = Vec::new();
    for (index, path) in o.scenes.iter().enumerate() {
        scenes.push(load_scene(index, path)?);
    }
    if o.device == Device::Gpu {
        for s in &scenes {
            s.loaded(Device::Gpu)?;
        }
    }
    let devices =
        if crate::render::gpu::adapters().is_empty() { vec![Device::Cpu] } else { vec![Device::Cpu, Device::Gpu] };
    let hello = Hello {
        version: 1,
        scenes: scenes.iter().map(|s| s.info.clone()).collect(),
        devices,
        device: o.device,
        limits: Limits {
            max_message_bytes: protocol::MAX_MESSAGE_BYTES,
            max_pixels: MAX_PIXELS,
            max_spp: MAX_SPP,
            max_bounces: MAX_BOUNCES,
        },
    };
    let state = Arc::new(State {
        scenes,
        hello,
        adapter: o.adapter,
        gpu: OnceLock::new(),
        passes: Semaphore::new(1),
        clients: AtomicUsize::new(0),
        max_clients: o.max_clients,
        renders: AtomicUsize::new(0),
    });
    if o.device == Device::Gpu {
        state.gpu()?;
    }
    let runtime = tokio::runtime::Runtime::new().context("starting the server's runtime")?;
    runtime.block_on(async move {
        let listener = tokio::net::TcpListener::bind(o.bind).await.with_context(|| format!("binding {}", o.bind))?;
        let addr = listener.local_addr()?;
        // An error, not a panic, where standard output is closed; standard output is
        // line-buffered, so the line goes out at its newline.
        writeln!(std::io::stdout(), "listening on http://{addr}/").context("writing the address")?;
        axum::serve(listener, router(state)).await.context("serving")
    })
}

fn router(state: Arc<State>) -> Router {
    Router::new()
        .route("/", get(|| async { ([(header::CONTENT_TYPE, "text/html; charset=utf-8")], page::INDEX_HTML) }))
        .route("/app.js", get(|| async { ([(header::CONTENT_TYPE, "text/javascript; charset=utf-8")], page::APP_JS) }))
        .route("/style.css", get(|| async { ([(header::CONTENT_TYPE, "text/css; charset=utf-8")], page::STYLE_CSS) }))
        .route("/status", get(status))
        .route("/ws", get(websocket))
        .with_state(state)
}

async fn websocket(ws: WebSocketUpgrade, AxumState(state): AxumState<Arc<State>>) -> impl IntoResponse {
    ws.max_message_size(TRANSPORT_MAX_BYTES)
        .max_frame_size(TRANSPORT_MAX_BYTES)
        .on_upgrade(move |socket| session::run(socket, state))
}

/// `GET /status`: clients connected and renders running, for monitoring (and the tests).
async fn status(AxumState(state): AxumState<Arc<State>>) -> impl IntoResponse {
    axum::Json(serde_json::json!({
        "clients": state.clients.load(Ordering::SeqCst),
        "renders": state.renders.load(Ordering::SeqCst),
        "max_clients": state.max_clients,
    }))
}

/// Loads one scene for the CPU and describes it for the page.
fn load_scene(index: usize, path: &Path) -> Result<SceneEntry> {
    let cpu = crate::cli::load(path, BuildSettings::default(), None)?;
    let c = &cpu.compiled;
    let (lo, hi) = c.world_bounds();
    let s = cpu.settings.resolve(lo, hi).with_context(|| path.display().to_string())?;
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| path.display().to_string());
    let mut warnings: Vec<String> = cpu.warnings.iter().map(|w| within_folder(w, path)).collect();
    if !crate::render::features::lit(c, &s) {
        warnings.push(format!("{name}: {}", crate::render::features::UNLIT));
    }
    let info = SceneInfo {
        index,
        name,
        triangles: c.scene.triangles.len(),
        lights: c.scene.lights.len(),
        nodes: c.tree().nodes.len(),
        tree_depth: c.tree().depth,
        width: s.width,
        height: s.height,
        spp: s.spp,
        bounces: s.max_bounces,
        seed: s.seed,
        camera: CameraInfo {
            eye: s.camera.eye.to_array(),
            target: s.camera.target.to_array(),
            up: s.camera.up.to_array(),
            fov: s.camera.fov_deg,
        },
        bounds_min: lo.to_array(),
        bounds_max: hi.to_array(),
        warnings,
    };
    Ok(SceneEntry { path: path.to_path_buf(), cpu, gpu: OnceLock::new(), info })
}

/// A loader's message (a warning, or a render's error from the GPU's lazy load) as a client reads
/// it: each path in the scene's folder written from that folder (`unlit.obj:3: ...`), so that the
/// page names the file and line without telling every client where the server keeps its files.
pub(crate) fn within_folder(message: &str, scene: &Path) -> String {
    let folder = scene.parent().map(|d| d.display().to_string()).unwrap_or_default();
    if folder.is_empty() {
        return message.to_string();
    }
    message.replace(&format!("{folder}{}", std::path::MAIN_SEPARATOR), "")
}

/// Counts a connection for as long as it lives.
pub(crate) struct ClientSlot(Arc<State>);

impl ClientSlot {
    /// A slot, unless `max_clients` are connected.
    pub fn take(state: &Arc<State>) -> Option<Self> {
        let n = state.clients.fetch_add(1, Ordering::SeqCst);
        if n >= state.max_clients {
            state.clients.fetch_sub(1, Ordering::SeqCst);
            return None;
        }
        Some(Self(state.clone()))
    }
}

impl Drop for ClientSlot {
    fn drop(&mut self) {
        self.0.clients.fetch_sub(1, Ordering::SeqCst);
    }
}
