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
# lavapipe's LLVM optimisation passes are most of a GPU test's time on a fresh machine: a test
# renders a few small images, and lavapipe compiles each of its pipelines (entry point and
# variant) once, seconds to tens of seconds of single-threaded work with the passes. Without
# them (gallivm's `nopt`) the shaders compile 2-2.5 times faster and run about half as fast; the
# images are the same bit for bit (the tests compare them with the CPU's). BENCHMARKS.md, "One
# compile per pipeline".
export GALLIVM_PERF="${GALLIVM_PERF:-nopt}"
if cargo nextest --version >/dev/null 2>&1; then
  # One process per test and two tests at a time across all test binaries, so that a binary's one
  # long lavapipe compile does not leave the other core idle, as `cargo test` (one binary at a
  # time) does. nextest runs no doctests, and the crates hold none (`cargo test --doc` would
  # build the host crate a second time, 4-5 minutes).
  cargo nextest run --release --workspace --exclude kernel --no-fail-fast "$@"
else
  cargo test --release --workspace --exclude kernel --no-fail-fast "$@"
fi
