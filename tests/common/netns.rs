//! Tests that open sockets run in network namespaces of their own, where only loopback exists,
//! so their traffic cannot leave the machine: a test calls `isolate(name)` first, which runs the
//! test again inside `unshare --net --pid --fork --mount-proc` (as root) and reports its outcome.
#![allow(dead_code)]
use std::process::Command;

const INSIDE: &str = "KDTRACE_TEST_NETNS";

/// Whether the caller is the outer run: then the test ran inside a namespace (and passed, or
/// this panics with its output), and the caller returns at once.
pub fn isolate(test: &str) -> bool {
    if std::env::var_os(INSIDE).is_some() {
        return false;
    }
    let exe = std::env::current_exe().unwrap();
    let out = Command::new("unshare")
        .args(["--net", "--pid", "--fork", "--mount-proc", "bash", "-c"])
        .arg(r#"ip link set lo up && exec "$0" --exact "$1" --nocapture --test-threads=1"#)
        .arg(&exe)
        .arg(test)
        .env(INSIDE, "1")
        .output()
        .expect("unshare runs (util-linux; the tests run as root)");
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "{test} inside its network namespace failed:\n{text}");
    assert!(text.contains("1 passed"), "{test} did not run inside its namespace:\n{text}");
    print!("{text}");
    true
}
