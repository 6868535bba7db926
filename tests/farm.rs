//! The farm drivers (farm/README.md): the Ray driver on a local cluster of a head and two
//! worker nodes, one of which is killed mid-render, and the Slurm job array and Kubernetes
//! Indexed Job recipes run locally index by index; each merged image must equal one
//! `kdtrace render` of the same settings byte for byte. The Ray cluster runs in a network
//! namespace of its own (`common::netns`), each worker node in a PID namespace of its own
//! (farm/local_cluster.sh), so its traffic stays on loopback and every Ray process ends with
//! the test. The Ray and Kubernetes tests need farm/.venv (farm/setup.sh --tests, which
//! scripts/setup.sh --tests runs); where it cannot be made (no PyPI) they print why and skip.
#[path = "common/netns.rs"]
mod netns;
#[path = "common/paths.rs"]
mod paths;

use netns::isolate;
use paths::repo;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// The test scene and render: tiny, so that the cluster's start-up is most of the time.
const SPP: &str = "64";
const RENDER_ARGS: [&str; 8] = ["--width", "32", "--height", "32", "--bounces", "1", "--seed", "3"];

fn scene() -> PathBuf {
    repo("scenes/cornell-box.toml")
}

fn kdtrace() -> &'static str {
    env!("CARGO_BIN_EXE_kdtrace")
}

/// A name no other run shares: inside a PID namespace every test process is pid 1.
fn unique() -> String {
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().subsec_nanos();
    format!("{}-{nanos:x}", std::process::id())
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("kdtrace-farm-{}-{name}", unique()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// farm/.venv's Python, made by farm/setup.sh --tests if need be (bounded; idempotent); None,
/// with the reason printed, where it cannot be made.
fn farm_python(test: &str) -> Option<PathBuf> {
    let out = Command::new("timeout")
        .args(["900", "bash"])
        .arg(repo("farm/setup.sh"))
        .arg("--tests")
        .output()
        .expect("timeout and bash run");
    if !out.status.success() {
        println!(
            "SKIPPED {test}: farm/setup.sh --tests could not make farm/.venv (no network to PyPI?):\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        return None;
    }
    Some(repo("farm/.venv/bin/python"))
}

/// `farm/test_recipes.py TEST` with the test's binary and scene.
fn recipe_test(python: &Path, test: &str) {
    let work = scratch(test);
    let out = Command::new(python)
        .arg(repo("farm/test_recipes.py"))
        .arg(test)
        .arg("--kdtrace")
        .arg(kdtrace())
        .arg("--scene")
        .arg(scene())
        .arg("--work")
        .arg(&work)
        .output()
        .unwrap();
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    print!("{text}");
    assert!(out.status.success(), "farm/test_recipes.py {test} failed:\n{text}");
    assert!(text.contains(&format!("{test}: ok")), "farm/test_recipes.py {test} did not finish:\n{text}");
    let _ = std::fs::remove_dir_all(&work);
}

#[test]
fn ranges_cover_the_render_in_blocks() {
    recipe_test(Path::new("python3"), "ranges");
}

#[test]
fn slurm_array_merges_to_the_single_render() {
    recipe_test(Path::new("python3"), "slurm");
}

#[test]
fn kubernetes_indexed_job_merges_to_the_single_render() {
    let Some(python) = farm_python("kubernetes_indexed_job_merges_to_the_single_render") else {
        return;
    };
    recipe_test(&python, "k8s");
}

/// Ray, one worker node killed mid-render: its range is run again on the other node, the driver
/// says so, and the merged image is still the single render's, byte for byte.
#[test]
fn ray_farm_survives_a_killed_worker() {
    let name = "ray_farm_survives_a_killed_worker";
    let Some(python) = farm_python(name) else {
        return;
    };
    if isolate(name) {
        return;
    }
    let t0 = Instant::now();
    let work = scratch("ray");
    // Ray's socket paths must stay under 108 bytes: a short folder of its own.
    let cluster = PathBuf::from(format!("/tmp/kdray-{}", unique()));
    let up = Command::new("timeout")
        .args(["120", "bash"])
        .arg(repo("farm/local_cluster.sh"))
        .arg(&cluster)
        .arg("2")
        .output()
        .unwrap();
    assert!(
        up.status.success(),
        "farm/local_cluster.sh did not bring up the cluster:\n{}",
        String::from_utf8_lossy(&up.stderr)
    );
    println!("cluster of a head and 2 workers up in {:.1} s", t0.elapsed().as_secs_f64());

    let want = work.join("single.exr");
    let o = Command::new(kdtrace())
        .arg("render")
        .arg(scene())
        .args(["--spp", SPP])
        .args(RENDER_ARGS)
        .arg("--out")
        .arg(&want)
        .output()
        .unwrap();
    assert!(o.status.success(), "kdtrace render: {}", String::from_utf8_lossy(&o.stderr));

    let got = work.join("farm.exr");
    let mut driver = Command::new(&python)
        .arg(repo("farm/ray_render.py"))
        .arg(scene())
        .args(["--spp", SPP, "--tasks", "8", "--address", "127.0.0.1:6379", "--json", "--kdtrace", kdtrace()])
        .args(RENDER_ARGS)
        .arg("--out")
        .arg(&got)
        // The driver's documented test hook: each task waits a second after reporting its
        // start, so the node killed below is certainly in the middle of a range.
        .env("KDTRACE_FARM_TEST_DELAY_S", "1")
        // As farm/local_cluster.sh's nodes: no token authentication (loopback only).
        .env("RAY_AUTH_MODE", "disabled")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdout = driver.stdout.take().unwrap();
    let json_reader = std::thread::spawn(move || {
        let mut s = String::new();
        stdout.read_to_string(&mut s).unwrap();
        s
    });
    let (tx, rx) = mpsc::channel();
    let stderr = driver.stderr.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines() {
            if tx.send(line.unwrap()).is_err() {
                break;
            }
        }
    });

    // Kill the worker node on which the first range starts, as soon as it starts.
    let deadline = Instant::now() + Duration::from_secs(240);
    let (mut log, mut killed) = (String::new(), None);
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match rx.recv_timeout(left) {
            Ok(line) => {
                println!("{line}");
                log += &line;
                log.push('\n');
                if killed.is_none() {
                    if let Some(ip) = line.split(" started on 127.0.0.").nth(1) {
                        let worker: u32 = ip.split(' ').next().unwrap().parse::<u32>().unwrap() - 1;
                        let pid = std::fs::read_to_string(cluster.join(format!("worker-{worker}.pid"))).unwrap();
                        let k = Command::new("kill").args(["-KILL", pid.trim()]).status().unwrap();
                        assert!(k.success(), "kill worker {worker} (pid {})", pid.trim());
                        println!(
                            "test: killed worker node {worker} (127.0.0.{}) at {:.1} s",
                            worker + 1,
                            t0.elapsed().as_secs_f64()
                        );
                        killed = Some(format!("127.0.0.{}", worker + 1));
                    }
                }
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => break,
            Err(mpsc::RecvTimeoutError::Timeout) => {
                let _ = driver.kill();
                panic!("the driver did not finish in 240 s; its log:\n{log}");
            }
        }
    }
    let status = driver.wait().unwrap();
    let report = json_reader.join().unwrap();
    assert!(status.success(), "farm/ray_render.py failed:\n{log}");
    let killed = killed.expect("no range started on a worker node");

    // The retry is in the driver's log and in its JSON report.
    assert!(log.contains("retried on another node (attempt 2)"), "no retry reported:\n{log}");
    // Ray may print lines of its own to stdout too; the report is the last line.
    let last = report.lines().rev().find(|l| l.starts_with('{'));
    let report: serde_json::Value = serde_json::from_str(last.unwrap_or_default())
        .unwrap_or_else(|e| panic!("no JSON report as the last line of the driver's stdout ({e}):\n{report}"));
    assert!(report["retries"].as_u64().unwrap() >= 1, "{report}");
    let ranges = report["ranges"].as_array().unwrap();
    assert_eq!(ranges.len(), 8);
    let retried: Vec<_> = ranges.iter().filter(|r| r["attempts"].as_u64().unwrap() >= 2).collect();
    assert!(!retried.is_empty(), "no range with 2 attempts: {report}");
    for r in &retried {
        let nodes = r["nodes"].as_array().unwrap();
        assert_eq!(nodes[0], killed.as_str(), "a retried range first ran on the killed node: {r}");
        assert_ne!(r["node"], killed.as_str(), "a retried range finished on the killed node: {r}");
    }

    let (got, want) = (std::fs::read(&got).unwrap(), std::fs::read(&want).unwrap());
    assert!(got == want, "the farm's merged EXR differs from `kdtrace render`'s");
    println!("farm render equals the single render byte for byte; {:.1} s in all", t0.elapsed().as_secs_f64());
    let _ = std::fs::remove_dir_all(&work);
    let _ = std::fs::remove_dir_all(&cluster);
}
