//! Inputs that are not regular files are refused at once with bounded memory (a FIFO named as a
//! material library would block forever, `/dev/zero` would be read until memory ran out); a write
//! that fails part-way leaves the previous output byte for byte and no temporary file; a UTF-8
//! byte-order mark does not swallow the first line, nor do lone-CR line ends make one line of a
//! file; a `usemtl` of an undefined material is named in a warning; an image whose buffers do not
//! fit in memory is refused, with the size it needs, before they are allocated.
#[path = "common/paths.rs"]
mod paths;
use paths::repo;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("kdtrace-io-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs kdtrace with `args`, killed after `limit` (a test failure, not a hang).
fn kdtrace_within(args: &[&str], limit: Duration) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_kdtrace"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            child.kill().unwrap();
            panic!("kdtrace {args:?} still running after {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

const TRIANGLE: &str = "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n";

fn render_args<'a>(scene: &'a str, out: &'a str) -> Vec<&'a str> {
    vec!["render", scene, "--out", out, "--spp", "1", "--width", "8", "--height", "8"]
}

#[test]
fn a_fifo_or_a_device_as_material_library_is_refused_at_once() {
    let d = dir("special");
    let fifo = d.join("lib.mtl");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let out = d.join("x.png");
    for (name, library) in [("fifo.obj", fifo.to_str().unwrap()), ("zero.obj", "/dev/zero")] {
        let obj = d.join(name);
        std::fs::write(&obj, format!("mtllib {library}\n{TRIANGLE}")).unwrap();
        let o = kdtrace_within(&render_args(obj.to_str().unwrap(), out.to_str().unwrap()), Duration::from_secs(20));
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{name}: {e}");
        assert!(e.contains(library) && e.contains("not a regular file"), "{name}: {e}");
        assert!(!out.exists());
    }
    // A folder, or a device, named as the scene itself.
    let folder = d.join("folder.obj");
    std::fs::create_dir(&folder).unwrap();
    for scene in [folder.to_str().unwrap(), "/dev/zero"] {
        let o = kdtrace_within(&["tree", scene], Duration::from_secs(20));
        assert_eq!(o.status.code(), Some(2), "{scene}: {}", stderr(&o));
    }
    let o = kdtrace_within(&["render", "/dev/null/x.kdc", "--out", out.to_str().unwrap()], Duration::from_secs(20));
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

#[test]
fn a_write_that_fails_leaves_the_previous_file_untouched() {
    let d = dir("ulimit");
    let out = d.join("cornell.png");
    let previous = b"the previous render, which must survive".to_vec();
    std::fs::write(&out, &previous).unwrap();
    // A 64×64 PNG of the box is a few KiB: past a 1 KiB file-size limit the write fails with
    // EFBIG (SIGXFSZ ignored, as a shell's `trap '' XFSZ` leaves it for the program it runs).
    let script = format!(
        "trap '' XFSZ; ulimit -f 1; exec {:?} render {:?} --out {:?} --spp 1 --width 64 --height 64",
        env!("CARGO_BIN_EXE_kdtrace"),
        repo("scenes/cornell-box.obj"),
        out
    );
    let o = Command::new("bash").arg("-c").arg(&script).output().unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("cornell.png") && e.contains("cannot write"), "{e}");
    assert_eq!(std::fs::read(&out).unwrap(), previous, "the previous file changed");
    let left: Vec<_> = std::fs::read_dir(&d).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(left.len(), 1, "temporary files left behind: {left:?}");
    // Without the limit the same command replaces it.
    let o = Command::new(env!("CARGO_BIN_EXE_kdtrace"))
        .args(render_args(repo("scenes/cornell-box.obj").to_str().unwrap(), out.to_str().unwrap()))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(&std::fs::read(&out).unwrap()[1..4], b"PNG");
}

#[test]
fn an_image_beyond_memory_is_refused_with_the_size_it_needs() {
    let d = dir("memory");
    let out = d.join("huge.png");
    // 16384² needs about 24 GiB of buffers; a 3 GiB address-space limit cannot hold them. Refused
    // before the buffers exist, not ended by a signal part-way.
    let script = format!(
        "ulimit -v 3000000; exec {:?} render {:?} --out {:?} --spp 1 --width 16384 --height 16384",
        env!("CARGO_BIN_EXE_kdtrace"),
        repo("scenes/cornell-box.obj"),
        out
    );
    let start = Instant::now();
    let o = Command::new("bash").arg("-c").arg(&script).output().unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("16384x16384") && e.contains("GiB"), "{e}");
    assert!(start.elapsed() < Duration::from_secs(60) && !out.exists());
}

fn tree_json(scene: &Path) -> serde_json::Value {
    let o =
        Command::new(env!("CARGO_BIN_EXE_kdtrace")).args(["tree", scene.to_str().unwrap(), "--json"]).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn a_byte_order_mark_does_not_swallow_the_first_line() {
    let d = dir("bom");
    // Without the mark, the first line would read as an unknown statement and the face would
    // name a vertex that does not exist.
    let plain = d.join("plain.obj");
    std::fs::write(&plain, format!("v 5 5 0\n{TRIANGLE}f 1 3 4\n")).unwrap();
    let marked = d.join("marked.obj");
    std::fs::write(&marked, [b"\xEF\xBB\xBF".as_slice(), &std::fs::read(&plain).unwrap()].concat()).unwrap();
    let (a, b) = (tree_json(&plain), tree_json(&marked));
    assert_eq!(a["triangles"], 2);
    assert_eq!(a["triangles"], b["triangles"]);
    assert_eq!(a["sah_cost"], b["sah_cost"]);
    // Classic Mac line ends (a CR alone) are line breaks too.
    let cr = d.join("cr.obj");
    std::fs::write(&cr, std::fs::read_to_string(&plain).unwrap().replace('\n', "\r")).unwrap();
    assert_eq!(tree_json(&cr)["triangles"], 2);
    // And a scene file with a mark.
    let toml = d.join("s.toml");
    std::fs::write(&toml, "\u{feff}[render]\nspp = 1\n[[mesh]]\nfile = \"plain.obj\"\n").unwrap();
    assert_eq!(tree_json(&toml)["triangles"], 2);
}

#[test]
fn an_undefined_material_is_named_in_a_warning() {
    let d = dir("usemtl");
    std::fs::write(d.join("m.mtl"), "newmtl light\nKe 1 1 1\nKd 0 0 0\n").unwrap();
    let obj = d.join("m.obj");
    std::fs::write(&obj, format!("mtllib m.mtl\n{TRIANGLE}usemtl Light\nf 1 3 2\n")).unwrap();
    let out = d.join("x.png");
    let o = Command::new(env!("CARGO_BIN_EXE_kdtrace"))
        .args(render_args(obj.to_str().unwrap(), out.to_str().unwrap()))
        .output()
        .unwrap();
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(e.contains("m.obj:6") && e.contains("\"Light\"") && e.contains("grey diffuse"), "{e}");
}
