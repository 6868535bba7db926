//! `kdtrace serve` over its websocket, with a Rust client: progressive frames whose last equals
//! `kdtrace render`'s image, pixel replays equal to the renderer's samples bit for bit, an
//! `error` for every malformed request with the connection still serving, renders stopped when
//! their client leaves or replaces them, and the client limit. Each test runs in a network
//! namespace of its own (`common::netns`).
#[path = "common/netns.rs"]
mod netns;
#[path = "common/paths.rs"]
mod paths;
#[path = "common/server.rs"]
mod server;

use netns::isolate;
use paths::{mesh, repo};
use serde_json::{json, Value};
use server::{scratch, Incoming, Server};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

fn box_scene() -> PathBuf {
    mesh("CornellBox-Original/CornellBox-Original.obj")
}

fn glass_scene() -> PathBuf {
    repo("tests/data/cornell-materials/cornell-glass.toml")
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap()
}

/// `kdtrace render SCENE ARGS --out OUT` on the CPU.
fn cli_render(scene: &Path, args: &[String], out: &Path) {
    let o = Command::new(env!("CARGO_BIN_EXE_kdtrace"))
        .arg("render")
        .arg(scene)
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    assert!(o.status.success(), "render failed: {}", String::from_utf8_lossy(&o.stderr));
}

fn csv(v: &Value) -> String {
    v.as_array().unwrap().iter().map(|x| x.to_string()).collect::<Vec<_>>().join(",")
}

/// The command line's flags for a websocket `render` request's fields.
fn cli_args(r: &Value) -> Vec<String> {
    let mut a = vec![];
    for (key, flag) in
        [("width", "--width"), ("height", "--height"), ("spp", "--spp"), ("bounces", "--bounces"), ("seed", "--seed")]
    {
        if let Some(v) = r.get(key) {
            a.extend([flag.to_string(), v.to_string()]);
        }
    }
    if let Some(c) = r.get("camera") {
        for (key, flag) in [("eye", "--eye"), ("target", "--target"), ("up", "--up")] {
            if let Some(v) = c.get(key) {
                a.extend([flag.to_string(), csv(v)]);
            }
        }
        if let Some(f) = c.get("fov") {
            a.extend(["--fov".to_string(), f.to_string()]);
        }
    }
    a
}

/// Frames and their progress messages until `done`: (progress, PNG) pairs in order.
async fn frames_until_done(c: &mut server::Client, secs: f64) -> Vec<(Value, Vec<u8>)> {
    let deadline = Instant::now() + Duration::from_secs_f64(secs);
    let mut frames = Vec::new();
    let mut progress: Option<Value> = None;
    loop {
        let left = deadline.saturating_duration_since(Instant::now()).as_secs_f64();
        assert!(left > 0.0, "the render did not finish within {secs} s ({} frames)", frames.len());
        match c.next(left).await {
            Incoming::Json(v) if v["type"] == "progress" => {
                assert!(progress.is_none(), "two progress messages without a frame between them");
                progress = Some(v);
            }
            Incoming::Json(v) if v["type"] == "done" => {
                assert!(progress.is_none(), "done before the last progress message's frame");
                return frames;
            }
            Incoming::Json(v) => panic!("unexpected message during a render: {v}"),
            Incoming::Frame(png) => {
                let p = progress.take().expect("a frame without a progress message before it");
                frames.push((p, png));
            }
        }
    }
}

fn decode_png(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let img = image::load_from_memory_with_format(bytes, image::ImageFormat::Png).unwrap().to_rgb8();
    (img.width(), img.height(), img.into_raw())
}

#[test]
fn frames_arrive_and_the_last_equals_the_cli_render() {
    if isolate("frames_arrive_and_the_last_equals_the_cli_render") {
        return;
    }
    let (a, b) = (box_scene(), glass_scene());
    let dir = scratch("frames");
    // A triangle that nothing lights: the page is told so, as the command line says it.
    let dark = server::unlit_scene(&dir);
    let server = Server::start(&[a.to_str().unwrap(), b.to_str().unwrap(), dark.to_str().unwrap()]);
    runtime().block_on(async {
        let (status, page) = server.get("/").await;
        assert!(status.contains("200"), "GET / answered {status}");
        assert!(page.contains("<canvas") && page.contains("/app.js"), "the page lacks its canvas or script");
        let (status, js) = server.get("/app.js").await;
        assert!(status.contains("200") && js.contains("WebSocket"), "GET /app.js answered {status}");

        let mut c = server.connect().await;
        let hello = c.next_of("hello", 10.0).await;
        let scenes = hello["scenes"].as_array().unwrap();
        assert_eq!(scenes.len(), 3);
        assert_eq!(scenes[0]["name"], "CornellBox-Original.obj");
        assert_eq!(scenes[1]["name"], "cornell-glass.toml");
        assert!(scenes[1]["triangles"].as_u64().unwrap() > 0 && scenes[1]["nodes"].as_u64().unwrap() > 0);
        for lit in &scenes[..2] {
            assert_eq!(lit["warnings"], json!([]), "a lit scene came with warnings: {lit}");
        }
        // The loader's warning names the file from the scene's folder, as the page shows it: the
        // folder the server keeps it in is not a client's business.
        let warnings: Vec<&str> =
            scenes[2]["warnings"].as_array().unwrap().iter().map(|w| w.as_str().unwrap()).collect();
        assert!(
            warnings.len() == 2
                && warnings[0].starts_with("unlit.obj: 1 zero-area triangles dropped")
                && warnings[1].starts_with("unlit.obj: nothing emits light"),
            "the unlit scene's warnings: {warnings:?}"
        );
        let folder = dir.to_str().unwrap();
        assert!(!hello.to_string().contains(folder), "the hello names the server's folder {folder}: {hello}");

        let request = json!({
            "type": "render", "scene": 1, "spp": 12, "bounces": 3, "width": 40, "height": 30, "seed": 7,
            "camera": {"eye": [0.3, 0.3, 0.75], "target": [0.27, 0.25, 0.0], "up": [0.0, 1.0, 0.0], "fov": 45.0}
        });
        c.send_json(&request).await;
        let frames = frames_until_done(&mut c, 120.0).await;
        assert!(frames.len() >= 2, "a 12-sample render came as {} frame(s); passes start at one sample", frames.len());
        let spps: Vec<u64> = frames.iter().map(|(p, _)| p["spp"].as_u64().unwrap()).collect();
        assert!(spps.windows(2).all(|w| w[0] < w[1]), "spp does not grow frame by frame: {spps:?}");
        // Passes start at one sample and at most double, but a client that reads late sees only
        // the newest frame (`serve::job`): the first one it gets may hold a few passes.
        assert!(spps[0] < 12, "the first frame came with the whole render: {spps:?}");
        assert_eq!(*spps.last().unwrap(), 12);
        for (p, _) in &frames {
            assert_eq!(p["target"], 12);
            assert_eq!((p["width"].as_u64(), p["height"].as_u64()), (Some(40), Some(30)));
            assert!(p["samples_per_s"].as_f64().unwrap() > 0.0);
        }

        let out = dir.join("cli.png");
        cli_render(&b, &cli_args(&request), &out);
        let want = decode_png(&std::fs::read(&out).unwrap());
        let got = decode_png(&frames.last().unwrap().1);
        assert_eq!((got.0, got.1), (40, 30));
        assert!(got == want, "the last frame differs from `kdtrace render`'s PNG of the same settings");
        // And an earlier frame is a different (noisier) image.
        assert!(decode_png(&frames[0].1) != want, "the first frame already equals the final image");
    });
}

#[test]
fn pixel_replays_equal_the_rendered_samples_bit_for_bit() {
    if isolate("pixel_replays_equal_the_rendered_samples_bit_for_bit") {
        return;
    }
    let scene = glass_scene();
    let server = Server::start(&[scene.to_str().unwrap()]);
    let dir = scratch("pixels");
    let (w, h, seed) = (24u32, 20u32, 5u32);
    let request = json!({"type": "render", "spp": 1, "bounces": 4, "width": w, "height": h, "seed": seed,
        "camera": {"eye": [0.28, 0.27, 0.8], "target": [0.278, 0.273, 0.0], "fov": 40.0}});
    let exr = dir.join("one.exr");
    cli_render(&scene, &cli_args(&request), &exr);
    let (_, _, want) = kdtrace::image::io::read_exr(&exr).unwrap();
    // Samples past 0 against the library's renderer: the sums of a one-sample range.
    let loaded = kdtrace::load(&scene, Default::default()).unwrap();
    runtime().block_on(async {
        let mut c = server.connect().await;
        c.next_of("hello", 10.0).await;
        c.send_json(&request).await;
        frames_until_done(&mut c, 60.0).await;
        let mut checked = 0;
        for i in 0..(w * h) {
            // Every third pixel, so that the test stays quick.
            if i % 3 != 0 {
                continue;
            }
            let (x, y) = (i % w, i / w);
            c.send_json(&json!({"type": "pixel", "x": x, "y": y, "sample": 0, "seed": seed})).await;
            let path = c.next_of("path", 30.0).await;
            assert_eq!(
                (path["x"].as_u64(), path["y"].as_u64(), path["sample"].as_u64()),
                (Some(x as u64), Some(y as u64), Some(0))
            );
            let got: Vec<f32> =
                path["radiance"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap() as f32).collect();
            let px = want[i as usize];
            for k in 0..3 {
                assert_eq!(
                    got[k].to_bits(),
                    px[k].to_bits(),
                    "pixel ({x}, {y}) channel {k}: replay {} vs render {}",
                    got[k],
                    px[k]
                );
            }
            assert!(!path["vertices"].as_array().unwrap().is_empty() || got == [0.0; 3]);
            checked += 1;
        }
        assert!(checked >= 150, "only {checked} pixels checked");

        let s = {
            let (lo, hi) = loaded.compiled.world_bounds();
            let flags = kdtrace::settings::SceneSettings {
                width: Some(w),
                height: Some(h),
                bounces: Some(4),
                seed: Some(seed),
                eye: Some([0.28, 0.27, 0.8]),
                target: Some([0.278, 0.273, 0.0]),
                fov_deg: Some(40.0),
                ..Default::default()
            };
            loaded.settings.overridden_by(&flags).resolve(lo, hi).unwrap()
        };
        for (x, y, sample) in [(3u32, 4u32, 1u32), (10, 10, 7), (20, 2, 31), (0, 19, 100), (12, 9, 3)] {
            c.send_json(&json!({"type": "pixel", "x": x, "y": y, "sample": sample, "seed": seed})).await;
            let path = c.next_of("path", 30.0).await;
            let got: Vec<f32> =
                path["radiance"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap() as f32).collect();
            let params = loaded.compiled.params(&s, sample, 1).unwrap();
            let view = loaded.compiled.view(&params);
            let v = shared::features::Variant::new(shared::features::FEATURES_ALL, &params);
            let (mut sum, mut sq, mut primary) = (Default::default(), Default::default(), 0);
            shared::integrator::render_samples(&view, &params, v, x, y, sample, 1, &mut sum, &mut sq, &mut primary);
            let sum: shared::glam::Vec4 = sum;
            let _ = sq;
            for (k, want) in [sum.x, sum.y, sum.z].into_iter().enumerate() {
                assert_eq!(got[k].to_bits(), want.to_bits(), "pixel ({x}, {y}) sample {sample} channel {k}");
            }
        }
    });
}

#[test]
fn every_malformed_message_gets_an_error_and_the_next_request_is_served() {
    if isolate("every_malformed_message_gets_an_error_and_the_next_request_is_served") {
        return;
    }
    let scene = box_scene();
    let server = Server::start(&[scene.to_str().unwrap()]);
    runtime().block_on(async {
        let mut c = server.connect().await;
        c.next_of("hello", 10.0).await;
        let big = format!(r#"{{"type":"render","pad":"{}"}}"#, "x".repeat(70 * 1024));
        let bad: Vec<(&str, String)> = vec![
            ("not JSON", "hello there".into()),
            ("an empty object", "{}".into()),
            ("an unknown type", r#"{"type":"teleport"}"#.into()),
            ("a type that is not a string", r#"{"type":7}"#.into()),
            ("an unknown field", r#"{"type":"render","colour":"red"}"#.into()),
            ("a scene out of range", r#"{"type":"render","scene":99}"#.into()),
            ("a negative scene", r#"{"type":"render","scene":-1}"#.into()),
            ("a zero width", r#"{"type":"render","width":0}"#.into()),
            ("too many pixels", r#"{"type":"render","width":16000,"height":16000}"#.into()),
            ("spp as a string", r#"{"type":"render","spp":"many"}"#.into()),
            ("zero spp", r#"{"type":"render","spp":0}"#.into()),
            ("too many bounces", r#"{"type":"render","bounces":100000}"#.into()),
            ("eye equal to target", r#"{"type":"render","camera":{"eye":[1,1,1],"target":[1,1,1]}}"#.into()),
            ("a NaN-like camera", r#"{"type":"render","camera":{"eye":[1e400,0,0]}}"#.into()),
            ("a field of view of 180", r#"{"type":"render","camera":{"fov":180}}"#.into()),
            ("an unknown device", r#"{"type":"render","device":"tpu"}"#.into()),
            ("a pixel outside the image", r#"{"type":"pixel","x":100000,"y":0}"#.into()),
            ("a negative pixel", r#"{"type":"pixel","x":-1,"y":0}"#.into()),
            ("a pixel without y", r#"{"type":"pixel","x":1}"#.into()),
            ("a message over 64 KiB", big),
            ("truncated JSON", r#"{"type":"render","spp":"#.into()),
        ];
        for (what, text) in &bad {
            c.send_text(text).await;
            let e = c.next_of("error", 10.0).await;
            assert!(!e["message"].as_str().unwrap_or("").is_empty(), "{what}: an error without a message");
        }
        c.send_binary(vec![1, 2, 3]).await;
        c.next_of("error", 10.0).await;
        // Still serving: a replay and a render.
        c.send_json(&json!({"type": "pixel", "x": 3, "y": 4})).await;
        let path = c.next_of("path", 30.0).await;
        assert_eq!(path["x"], 3);
        c.send_json(&json!({"type": "render", "spp": 2, "width": 16, "height": 16})).await;
        let frames = frames_until_done(&mut c, 60.0).await;
        assert_eq!(frames.last().unwrap().0["spp"], 2);
    });
}

/// Polls `/status` until `renders` is `want`, within `secs`.
async fn wait_for_renders(server: &Server, want: u64, secs: f64) -> Value {
    let deadline = Instant::now() + Duration::from_secs_f64(secs);
    loop {
        let (_, body) = server.get("/status").await;
        let v: Value = serde_json::from_str(&body).unwrap();
        if v["renders"] == want {
            return v;
        }
        assert!(Instant::now() < deadline, "renders still {} after {secs} s (want {want})", v["renders"]);
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

#[test]
fn leaving_or_replacing_or_stopping_ends_the_render_and_clients_are_limited() {
    if isolate("leaving_or_replacing_or_stopping_ends_the_render_and_clients_are_limited") {
        return;
    }
    let scene = box_scene();
    let server = Server::start(&[scene.to_str().unwrap(), "--max-clients", "2"]);
    let long = json!({"type": "render", "spp": 1000000, "width": 64, "height": 64});
    runtime().block_on(async {
        // A client that leaves mid-render: its render stops.
        let mut a = server.connect().await;
        a.next_of("hello", 10.0).await;
        a.send_json(&long).await;
        a.next_of("progress", 30.0).await;
        wait_for_renders(&server, 1, 5.0).await;
        drop(a);
        wait_for_renders(&server, 0, 10.0).await;

        // A new render replaces the running one; `stop` ends it.
        let mut b = server.connect().await;
        b.next_of("hello", 10.0).await;
        b.send_json(&long).await;
        b.next_of("progress", 30.0).await;
        b.send_json(&json!({"type": "render", "spp": 1000000, "width": 32, "height": 32})).await;
        tokio::time::sleep(Duration::from_millis(300)).await;
        wait_for_renders(&server, 1, 10.0).await;
        b.send_json(&json!({"type": "stop"})).await;
        wait_for_renders(&server, 0, 10.0).await;

        // Two clients at most: a third gets an error.
        let mut c2 = server.connect().await;
        c2.next_of("hello", 10.0).await;
        let mut c3 = server.connect().await;
        let e = c3.next_of("error", 10.0).await;
        assert!(e["message"].as_str().unwrap().contains("most clients"), "{e}");
        drop(c3);
        drop(c2);
        // Once one leaves, a new client is served.
        tokio::time::sleep(Duration::from_millis(200)).await;
        let mut c4 = server.connect().await;
        c4.next_of("hello", 10.0).await;
        drop(b);
    });
}

#[test]
fn gpu_renders_and_the_cost_view_equal_the_cli() {
    if isolate("gpu_renders_and_the_cost_view_equal_the_cli") {
        return;
    }
    let scene = box_scene();
    // lavapipe: the GPU the tests have, and the one the CLI picks with the same name.
    let server = Server::start(&[scene.to_str().unwrap(), "--adapter", "llvmpipe"]);
    let dir = scratch("gpu");
    runtime().block_on(async {
        let mut c = server.connect().await;
        let hello = c.next_of("hello", 10.0).await;
        assert!(hello["devices"].as_array().unwrap().iter().any(|d| d == "gpu"), "no gpu in {hello}");
        for (device, aov) in [("gpu", "radiance"), ("cpu", "cost"), ("gpu", "cost")] {
            let request = json!({"type": "render", "spp": 5, "width": 24, "height": 24, "bounces": 2,
                "device": device, "aov": aov});
            c.send_json(&request).await;
            let frames = frames_until_done(&mut c, 120.0).await;
            let (progress, png) = frames.last().unwrap();
            assert_eq!(progress["spp"], 5);
            if device == "gpu" {
                assert!(progress["device"].as_str().unwrap().contains("llvmpipe"), "{progress}");
            }
            let out = dir.join(format!("{device}-{aov}.png"));
            let mut args = cli_args(&request);
            args.extend(["--device", device, "--aov", aov, "--adapter", "llvmpipe"].map(String::from));
            cli_render(&scene, &args, &out);
            assert!(
                decode_png(png) == decode_png(&std::fs::read(&out).unwrap()),
                "{device} {aov}: the last frame differs from the CLI's PNG"
            );
        }
    });
}
