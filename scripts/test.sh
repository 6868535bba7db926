#!/usr/bin/env bash
# Sets up (scripts/setup.sh --tests), checks formatting and clippy, and runs the whole test suite, GPU
# tests on lavapipe included. Needs only this repository (the tests' meshes are in tests/data).
# One profile (release) for everything: the brute-force traversal tests need optimised code.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh --tests
# Habits first (seconds): formatting, then clippy on the host and shared crates with every
# warning an error (the kernel builds for SPIR-V only).
cargo fmt --all --check
cargo clippy --release --workspace --exclude kernel --all-targets -- -D warnings
cargo test --release --workspace --exclude kernel --no-fail-fast "$@"
