#!/usr/bin/env bash
# The web UI's figures: the load test (20 clients rendering and clicking for 30 s; p50/p99 pixel
# reply times, frames, memory) and the README's screenshot of the page with a debugged path.
# Both run in network namespaces of their own (tests/common/netns.rs), as root.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh --tests
mkdir -p bench/results bench/renders
cargo test --release -p kdtrace --test serve_load -- --nocapture 2>&1 | tee bench/results/serve_load.txt |
  grep "serve load:"
KDTRACE_SCREENSHOT="$PWD/bench/renders/serve-debugger.png" \
  cargo test --release -p kdtrace --test serve_browser -- --nocapture 2>&1 | grep -E "screenshot|PASS|FAIL"
