//! One websocket connection: its requests in, its frames, replays and errors out. A bad message
//! gets an `error` reply and the connection goes on; leaving stops the client's render.
use super::job::{self, Job, Update};
use super::protocol::{ClientMessage, PixelRequest, RenderRequest, ServerMessage, MAX_MESSAGE_BYTES};
use super::{ClientSlot, State, MAX_PIXELS};
use crate::cli::Device;
use crate::settings::{Aov, RenderSettings, SceneSettings};
use anyhow::{bail, Result};
use axum::extract::ws::{Message, WebSocket};
use std::sync::Arc;
use tokio::sync::{mpsc, watch};

/// Replays a client may have in flight; more get an `error` reply.
pub const MAX_PENDING_PIXELS: usize = 4;

/// The client's latest render: what a `pixel` replays.
struct Latest {
    scene: usize,
    settings: RenderSettings,
}

pub async fn run(mut socket: WebSocket, state: Arc<State>) {
    let Some(_slot) = ClientSlot::take(&state) else {
        let full = format!("the server has its most clients ({}); try again later", state.max_clients);
        let _ = send(&mut socket, &ServerMessage::Error { message: full }).await;
        let _ = socket.send(Message::Close(None)).await;
        return;
    };
    if send(&mut socket, &ServerMessage::Hello(state.hello.clone())).await.is_err() {
        return;
    }
    let mut latest: Option<Latest> = None;
    let mut job: Option<(Job, watch::Receiver<Update>)> = None;
    let (replies, mut replies_rx) = mpsc::channel::<String>(MAX_PENDING_PIXELS);
    let mut pending = 0usize;
    loop {
        tokio::select! {
            incoming = socket.recv() => {
                let Some(Ok(msg)) = incoming else { break };
                let text = match msg {
                    Message::Text(t) => t,
                    Message::Close(_) => break,
                    Message::Binary(_) => {
                        if error(&mut socket, "binary messages are not part of the protocol; send JSON text").await.is_err() {
                            break;
                        }
                        continue;
                    }
                    // Pings are answered by the transport.
                    _ => continue,
                };
                let outcome = handle(&state, text.as_str(), &mut latest, &mut job, &mut pending, &replies).await;
                if let Err(e) = outcome {
                    if error(&mut socket, &format!("{e:#}")).await.is_err() {
                        break;
                    }
                }
            }
            Some(reply) = replies_rx.recv() => {
                pending -= 1;
                if socket.send(Message::Text(reply.into())).await.is_err() {
                    break;
                }
            }
            update = changed(&mut job) => {
                let Some(update) = update else { job = None; continue };
                let finished = match update {
                    Update::Started => false,
                    Update::Frame(f) => {
                        if send(&mut socket, &ServerMessage::Progress(f.progress.clone())).await.is_err()
                            || socket.send(Message::Binary(f.png.clone().into())).await.is_err()
                        {
                            break;
                        }
                        if f.last && send(&mut socket, &ServerMessage::Done(f.progress.clone())).await.is_err() {
                            break;
                        }
                        f.last
                    }
                    Update::Failed(message) => {
                        if error(&mut socket, &format!("render failed: {message}")).await.is_err() {
                            break;
                        }
                        true
                    }
                };
                if finished {
                    job = None;
                }
            }
        }
    }
    if let Some((j, _)) = job {
        j.stop();
    }
}

/// The next update of the running render; `None` once it has gone; never resolves without one.
async fn changed(job: &mut Option<(Job, watch::Receiver<Update>)>) -> Option<Update> {
    match job {
        Some((_, rx)) => match rx.changed().await {
            Ok(()) => Some(rx.borrow_and_update().clone()),
            Err(_) => None,
        },
        None => std::future::pending().await,
    }
}

async fn handle(
    state: &Arc<State>,
    text: &str,
    latest: &mut Option<Latest>,
    job: &mut Option<(Job, watch::Receiver<Update>)>,
    pending: &mut usize,
    replies: &mpsc::Sender<String>,
) -> Result<()> {
    if text.len() > MAX_MESSAGE_BYTES {
        bail!("message of {} bytes; the most is {MAX_MESSAGE_BYTES}", text.len());
    }
    let msg: ClientMessage = serde_json::from_str(text).map_err(|e| anyhow::anyhow!("bad message: {e}"))?;
    match msg {
        ClientMessage::Render(r) => {
            let (scene, settings, device) = resolve(state, &r)?;
            if let Some((old, _)) = job.take() {
                old.stop();
            }
            *latest = Some(Latest { scene, settings });
            *job = Some(job::start(state.clone(), job::Spec { scene, settings, device }));
        }
        ClientMessage::Stop => {
            if let Some((old, _)) = job.take() {
                old.stop();
            }
        }
        ClientMessage::Pixel(p) => {
            if *pending >= MAX_PENDING_PIXELS {
                bail!("{MAX_PENDING_PIXELS} pixel replays are already under way; wait for their replies");
            }
            let (scene, settings) = match latest {
                Some(l) => (l.scene, l.settings),
                None => {
                    let (scene, settings, _) = resolve(state, &RenderRequest::default())?;
                    (scene, settings)
                }
            };
            check_pixel(&p, &settings)?;
            *pending += 1;
            let (state, replies) = (state.clone(), replies.clone());
            tokio::task::spawn_blocking(move || {
                let reply = replay(&state, scene, settings, p).unwrap_or_else(|e| {
                    serde_json::to_string(&ServerMessage::Error { message: format!("{e:#}") })
                        .unwrap_or_else(|_| String::from(r#"{"type":"error","message":"replay failed"}"#))
                });
                // The client may have gone; then nobody needs the reply.
                let _ = replies.blocking_send(reply);
            });
        }
    }
    Ok(())
}

/// A `render` request against the scene's own settings, as the command line's flags are.
fn resolve(state: &State, r: &RenderRequest) -> Result<(usize, RenderSettings, Device)> {
    let scene = r.scene.unwrap_or(0);
    let Some(entry) = state.scenes.get(scene) else {
        bail!("scene {scene} does not exist: the server has {} (0 to {})", state.scenes.len(), state.scenes.len() - 1);
    };
    let device = r.device.unwrap_or(state.hello.device);
    if !state.hello.devices.contains(&device) {
        bail!("this server has no {} device", device.name());
    }
    let camera = r.camera.unwrap_or_default();
    let flags = SceneSettings {
        width: r.width,
        height: r.height,
        spp: r.spp,
        bounces: r.bounces,
        seed: r.seed,
        eye: camera.eye,
        target: camera.target,
        up: camera.up,
        fov_deg: camera.fov,
        ..Default::default()
    };
    let c = &entry.cpu.compiled;
    let (lo, hi) = c.world_bounds();
    let mut s = entry.cpu.settings.overridden_by(&flags).resolve(lo, hi)?;
    // A time limit or adaptive sampling from the scene file does not apply: the page stops a
    // render by moving on.
    s.time_limit_s = None;
    s.aov = r.aov.unwrap_or(Aov::Radiance);
    if s.width as u64 * s.height as u64 > MAX_PIXELS {
        bail!("{}x{} is {} pixels; the most is {MAX_PIXELS}", s.width, s.height, s.width as u64 * s.height as u64);
    }
    s.check()?;
    // The camera placed against the scene, before any work.
    c.check_camera(&s)?;
    Ok((scene, s, device))
}

fn check_pixel(p: &PixelRequest, s: &RenderSettings) -> Result<()> {
    if p.x >= s.width || p.y >= s.height {
        bail!("pixel ({}, {}) lies outside the {}x{} image", p.x, p.y, s.width, s.height);
    }
    Ok(())
}

/// Replays one sample on the CPU with the render's settings and `p`'s seed; the `path` message.
fn replay(state: &State, scene: usize, mut s: RenderSettings, p: PixelRequest) -> Result<String> {
    s.seed = p.seed.unwrap_or(s.seed);
    s.aov = Aov::Radiance;
    let record = crate::debug::replay(&state.scenes[scene].cpu.compiled, &s, p.x, p.y, p.sample)?;
    let msg = ServerMessage::Path { record: &record };
    Ok(serde_json::to_string(&msg)?)
}

async fn send(socket: &mut WebSocket, msg: &ServerMessage<'_>) -> Result<()> {
    let text = serde_json::to_string(msg)?;
    socket.send(Message::Text(text.into())).await?;
    Ok(())
}

async fn error(socket: &mut WebSocket, message: &str) -> Result<()> {
    send(socket, &ServerMessage::Error { message: message.to_string() }).await
}
