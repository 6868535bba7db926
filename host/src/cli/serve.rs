//! `kdtrace serve`: the web UI and remote debugger (`crate::serve`).
use super::args::Device;
use anyhow::Result;
use clap::Args;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args)]
pub struct ServeArgs {
    /// Scenes the page can switch between (.obj, .toml or .kdc).
    #[arg(required = true)]
    scenes: Vec<PathBuf>,
    /// Address and port to listen on; port 0 picks a free one (the address is printed). A
    /// non-loopback address is reachable from other machines: a warning says so.
    #[arg(long, default_value = "127.0.0.1:8080")]
    bind: SocketAddr,
    /// The device a render uses unless the page asks for another.
    #[arg(long, value_enum, default_value_t = Device::Cpu)]
    device: Device,
    /// GPU adapter name (a substring, case-insensitive); the first one otherwise.
    #[arg(long)]
    adapter: Option<String>,
    /// Most clients connected at once; more get an error and are closed.
    #[arg(long, default_value_t = 32, value_parser = clap::value_parser!(u64).range(1..=1024))]
    max_clients: u64,
}

pub fn run(a: ServeArgs) -> Result<ExitCode> {
    crate::serve::run(crate::serve::Options {
        scenes: a.scenes,
        bind: a.bind,
        device: a.device,
        adapter: a.adapter,
        max_clients: a.max_clients as usize,
    })?;
    Ok(ExitCode::SUCCESS)
}
