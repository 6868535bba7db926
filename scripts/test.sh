#!/usr/bin/env bash
# Sets up (scripts/setup.sh) and runs the whole test suite, GPU tests on lavapipe included.
# One profile (release) for everything: the brute-force traversal tests need optimised code.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
cargo test --release --workspace --exclude kernel "$@"
