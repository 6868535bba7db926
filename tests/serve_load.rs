//! A bounded load test of `kdtrace serve`: 20 clients for 30 s (`KDTRACE_LOAD_CLIENTS`,
//! `KDTRACE_LOAD_SECONDS`), each moving the camera (a new render) and clicking a pixel (a replay)
//! over and over. The server must answer every replay, keep sending frames to every client, keep
//! its memory bounded and serve a new client afterwards. Prints the figures as one JSON line
//! (`bench/serve_load.sh` collects them for BENCHMARKS.md).
#[path = "common/netns.rs"]
mod netns;
#[path = "common/paths.rs"]
mod paths;
#[path = "common/server.rs"]
mod server;

use netns::isolate;
use paths::mesh;
use serde_json::json;
use server::{Incoming, Server};
use std::time::{Duration, Instant};

fn env_or(name: &str, default: u64) -> u64 {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

/// What one client saw.
#[derive(Default)]
struct Seen {
    frames: u64,
    renders: u64,
    /// Seconds from each `pixel` request to its `path` reply.
    replies: Vec<f64>,
    errors: Vec<String>,
}

async fn client(server: &Server, id: u64, until: Instant) -> Seen {
    let mut seen = Seen::default();
    let mut c = server.connect().await;
    c.next_of("hello", 30.0).await;
    let mut step = 0u64;
    while Instant::now() < until {
        // A camera on a circle around the box, different per client and step.
        let a = (id as f64 * 0.7 + step as f64 * 0.15).sin() * 0.4;
        let eye = [a.sin() * 3.4, 1.0, a.cos() * 3.4];
        c.send_json(&json!({"type": "render", "spp": 100000, "width": 64, "height": 64, "bounces": 4,
            "camera": {"eye": eye, "target": [0.0, 1.0, 0.0], "fov": 40.0}}))
            .await;
        seen.renders += 1;
        // Look at the image for a while (frames arrive), then click a pixel.
        let look = Instant::now() + Duration::from_millis(400);
        while Instant::now() < look {
            let left = look.saturating_duration_since(Instant::now()).as_secs_f64().max(0.01);
            match tokio::time::timeout(Duration::from_secs_f64(left), c.next(60.0)).await {
                Ok(Incoming::Frame(_)) => seen.frames += 1,
                Ok(Incoming::Json(v)) if v["type"] == "error" => seen.errors.push(v.to_string()),
                Ok(_) => {}
                Err(_) => break,
            }
        }
        let (x, y) = ((id * 7 + step * 13) % 64, (id * 11 + step * 5) % 64);
        let asked = Instant::now();
        c.send_json(&json!({"type": "pixel", "x": x, "y": y, "sample": step % 16})).await;
        loop {
            match c.next(60.0).await {
                Incoming::Frame(_) => seen.frames += 1,
                Incoming::Json(v) if v["type"] == "path" => {
                    seen.replies.push(asked.elapsed().as_secs_f64());
                    break;
                }
                Incoming::Json(v) if v["type"] == "error" => {
                    seen.errors.push(v.to_string());
                    break;
                }
                Incoming::Json(_) => {}
            }
        }
        step += 1;
    }
    seen
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

#[test]
fn twenty_clients_rendering_and_clicking_stay_served() {
    if isolate("twenty_clients_rendering_and_clicking_stay_served") {
        return;
    }
    let clients = env_or("KDTRACE_LOAD_CLIENTS", 20);
    let seconds = env_or("KDTRACE_LOAD_SECONDS", 30);
    let scene = mesh("CornellBox-Original/CornellBox-Original.obj");
    let server = Server::start(&[scene.to_str().unwrap()]);
    let (rss_idle, _) = server.memory_kib();
    let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
    let start = Instant::now();
    let until = start + Duration::from_secs(seconds);
    let seen: Vec<Seen> = rt.block_on(async {
        let server = &server;
        let tasks = (0..clients).map(|id| client(server, id, until));
        futures_util::future::join_all(tasks).await
    });
    let wall = start.elapsed().as_secs_f64();
    let (rss_after, rss_peak) = server.memory_kib();

    let mut replies: Vec<f64> = seen.iter().flat_map(|s| s.replies.iter().copied()).collect();
    replies.sort_by(f64::total_cmp);
    let frames: Vec<u64> = seen.iter().map(|s| s.frames).collect();
    let errors: Vec<&String> = seen.iter().flat_map(|s| &s.errors).collect();

    // Afterwards a new client is served at once.
    let fresh_s = rt.block_on(async {
        let t = Instant::now();
        let mut c = server.connect().await;
        c.next_of("hello", 10.0).await;
        c.send_json(&json!({"type": "render", "spp": 1, "width": 32, "height": 32})).await;
        c.next_of("done", 30.0).await;
        t.elapsed().as_secs_f64()
    });
    let report = json!({
        "clients": clients,
        "seconds": wall,
        "renders": seen.iter().map(|s| s.renders).sum::<u64>(),
        "frames": frames.iter().sum::<u64>(),
        "frames_min_per_client": frames.iter().min(),
        "frames_max_per_client": frames.iter().max(),
        "pixel_replies": replies.len(),
        "pixel_p50_s": percentile(&replies, 0.5),
        "pixel_p99_s": percentile(&replies, 0.99),
        "pixel_max_s": replies.last(),
        "errors": errors.len(),
        "rss_idle_mib": rss_idle / 1024,
        "rss_after_mib": rss_after / 1024,
        "rss_peak_mib": rss_peak / 1024,
        "new_client_first_image_s": fresh_s,
    });
    println!("serve load: {report}");

    assert!(errors.is_empty(), "errors under load: {errors:?}");
    assert!(frames.iter().all(|&f| f > 0), "a client got no frame: {frames:?}");
    // Fair shares: passes are taken in turn, so no client gets far fewer frames than another.
    let (least, most) = (*frames.iter().min().unwrap(), *frames.iter().max().unwrap());
    assert!(3 * least >= most, "unfair: frames per client from {least} to {most}");
    let asked: usize = seen.iter().map(|s| s.renders as usize).sum();
    assert_eq!(replies.len(), asked, "every click gets its path");
    let p99 = percentile(&replies, 0.99);
    assert!(p99 < 2.0, "p99 pixel reply time {p99:.3} s under load");
    // Bounded: 20 clients of 64×64 renders need little; a leak of frames or replies would show.
    assert!(rss_peak < 1024 * 1024, "the server's peak memory reached {} MiB", rss_peak / 1024);
    assert!(fresh_s < 10.0, "a new client waited {fresh_s:.1} s for its image after the load");
}
