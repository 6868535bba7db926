//! The page of `kdtrace serve` in real headless Chromium (`tests/web/browser.mjs`, Debian's
//! `chromium` driven by npm's `playwright-core`, both installed by scripts/setup.sh): it loads,
//! shows the scene within seconds, changes the view when dragged, draws a clicked pixel's path
//! and shows a scene's warnings. Server, browser and test share a network namespace of their own (`common::netns`).
#[path = "common/netns.rs"]
mod netns;
#[path = "common/paths.rs"]
mod paths;
#[path = "common/server.rs"]
mod server;

use netns::isolate;
use paths::{mesh, repo};
use server::Server;
use std::process::Command;

#[test]
fn the_page_renders_moves_and_debugs_a_pixel_in_chromium() {
    if isolate("the_page_renders_moves_and_debugs_a_pixel_in_chromium") {
        return;
    }
    let web = repo("tests/web");
    assert!(
        web.join("node_modules/playwright-core").exists(),
        "tests/web/node_modules lacks playwright-core: scripts/setup.sh installs it (npm ci in tests/web)"
    );
    let scene = mesh("CornellBox-Original/CornellBox-Original.obj");
    // A second scene that nothing lights: choosing it shows the warning beside the image.
    let dark = server::unlit_scene(&server::scratch("browser"));
    let server = Server::start(&[scene.to_str().unwrap(), dark.to_str().unwrap()]);
    let mut cmd = Command::new("node");
    cmd.arg(web.join("browser.mjs")).arg(format!("http://{}/", server.addr));
    if let Some(shot) = std::env::var_os("KDTRACE_SCREENSHOT") {
        cmd.arg(shot);
    }
    let out = cmd.output().expect("node runs (scripts/setup.sh installs nodejs)");
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    println!("{text}");
    assert!(out.status.success() && text.contains("PASS"), "the browser test failed:\n{text}");
}
