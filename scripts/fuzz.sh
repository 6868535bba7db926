#!/usr/bin/env bash
# Runs every cargo-fuzz target (fuzz/fuzz_targets) for a bounded time from its seed corpus and
# reports executions and findings. Not part of CI (it needs cargo-fuzz and builds the fuzz
# workspace with coverage instrumentation, several minutes on 2 cores).
# Usage: scripts/fuzz.sh [SECONDS_PER_TARGET]          (default 60)
#   needs: cargo install cargo-fuzz   (uses the pinned nightly of rust-toolchain.toml)
# Crashes land in fuzz/artifacts/<target>/; the new corpus entries in fuzz/corpus/<target>/ are
# git-ignored except the committed seed-* files.
set -euo pipefail
cd "$(dirname "$0")/../fuzz"
seconds=${1:-60}
# No sanitizer: the code under test is safe Rust, so what there is to find is panics, aborts,
# overflowing allocations and hangs, which libFuzzer reports on its own; -O builds release.
flags=(-s none -O)
cargo fuzz build "${flags[@]}"
status=0
for target in $(cargo fuzz list); do
  log=$(mktemp)
  echo "== $target: ${seconds}s"
  if cargo fuzz run "${flags[@]}" "$target" "corpus/$target" -- \
      -max_total_time="$seconds" -max_len=16384 -timeout=10 -rss_limit_mb=4096 -print_final_stats=1 >"$log" 2>&1; then
    echo "   no crash"
  else
    echo "   FINDING: $(grep -m1 -o 'artifacts/[^ ]*' "$log" || echo "see fuzz/artifacts/$target/")"
    grep -m1 -A1 "panicked at\|ERROR: libFuzzer" "$log" | sed 's/^/   /' || tail -20 "$log"
    status=1
  fi
  grep -E "stat::number_of_executed_units|stat::peak_rss_mb|cov: .*corp:" "$log" | tail -3 | sed 's/^/   /'
  rm -f "$log"
done
exit $status
