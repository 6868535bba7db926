//! A `kdtrace serve` process for the server's tests, on a free loopback port, stopped when
//! dropped; and a websocket client that reads the protocol's messages with time limits.
#![allow(dead_code)]
use futures_util::{SinkExt, StreamExt};
use serde_json::Value;
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::Duration;
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};

/// A fresh folder for a server test's files, named for this process and `name`.
pub fn scratch(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("kdtrace-serve-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `dir/unlit.obj`: one triangle and nothing that emits light, a scene the server must warn of,
/// and a second triangle of zero area, which the loader drops with a warning naming the file.
pub fn unlit_scene(dir: &std::path::Path) -> std::path::PathBuf {
    let path = dir.join("unlit.obj");
    std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\n").unwrap();
    path
}

pub struct Server {
    child: Child,
    /// host:port it listens on.
    pub addr: String,
}

impl Server {
    /// `kdtrace serve ARGS --bind 127.0.0.1:0`, once it prints where it listens.
    pub fn start(args: &[&str]) -> Server {
        let mut child = Command::new(env!("CARGO_BIN_EXE_kdtrace"))
            .arg("serve")
            .args(args)
            .args(["--bind", "127.0.0.1:0"])
            .stdout(Stdio::piped())
            .spawn()
            .unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
        let addr = line
            .trim()
            .strip_prefix("listening on http://")
            .and_then(|a| a.strip_suffix('/'))
            .unwrap_or_else(|| panic!("unexpected first line from serve: {line:?}"))
            .to_string();
        Server { child, addr }
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    pub async fn connect(&self) -> Client {
        let (ws, _) = tokio_tungstenite::connect_async(format!("ws://{}/ws", self.addr)).await.unwrap();
        Client { ws }
    }

    /// GET `path` over plain HTTP/1.0: (status line, body).
    pub async fn get(&self, path: &str) -> (String, String) {
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        let mut s = TcpStream::connect(&self.addr).await.unwrap();
        s.write_all(format!("GET {path} HTTP/1.0\r\nHost: {}\r\n\r\n", self.addr).as_bytes()).await.unwrap();
        let mut text = String::new();
        s.read_to_string(&mut text).await.unwrap();
        let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
        (head.lines().next().unwrap_or("").to_string(), body.to_string())
    }

    /// The server's resident memory now and at its peak, in KiB (`/proc/PID/status`).
    pub fn memory_kib(&self) -> (u64, u64) {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.pid())).unwrap();
        let field = |name: &str| {
            status
                .lines()
                .find_map(|l| l.strip_prefix(name))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
                .unwrap_or(0)
        };
        (field("VmRSS:"), field("VmHWM:"))
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// One message from the server: JSON text or a binary frame.
#[derive(Debug)]
pub enum Incoming {
    Json(Value),
    Frame(Vec<u8>),
}

pub struct Client {
    pub ws: WebSocketStream<MaybeTlsStream<TcpStream>>,
}

impl Client {
    pub async fn send_json(&mut self, v: &Value) {
        self.ws.send(Message::text(v.to_string())).await.unwrap();
    }

    pub async fn send_text(&mut self, t: &str) {
        self.ws.send(Message::text(t.to_string())).await.unwrap();
    }

    pub async fn send_binary(&mut self, b: Vec<u8>) {
        self.ws.send(Message::binary(b)).await.unwrap();
    }

    /// The next message, within `secs` seconds (a panic otherwise, or when the server closes).
    pub async fn next(&mut self, secs: f64) -> Incoming {
        loop {
            let m = tokio::time::timeout(Duration::from_secs_f64(secs), self.ws.next())
                .await
                .unwrap_or_else(|_| panic!("no message from the server within {secs} s"))
                .expect("the server closed the connection")
                .expect("websocket error");
            match m {
                Message::Text(t) => return Incoming::Json(serde_json::from_str(t.as_str()).unwrap()),
                Message::Binary(b) => return Incoming::Frame(b.to_vec()),
                Message::Close(c) => panic!("the server closed the connection: {c:?}"),
                _ => continue,
            }
        }
    }

    /// The next JSON message of type `kind`, skipping others (frames, progress).
    pub async fn next_of(&mut self, kind: &str, secs: f64) -> Value {
        let deadline = std::time::Instant::now() + Duration::from_secs_f64(secs);
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now()).as_secs_f64();
            assert!(left > 0.0, "no {kind:?} message within {secs} s");
            if let Incoming::Json(v) = self.next(left).await {
                if v["type"] == kind {
                    return v;
                }
            }
        }
    }
}
