#!/usr/bin/env bash
# Time against error: kdtrace (CPU, GPU) against Blender Cycles and Mitsuba 3 on the same scenes
# (bench/time_vs_error.py; how the scenes are made equal: bench/peers/*.py, ../shared/docs/peers.md).
# Sets up bench/.venv (bpy 5.0.1, mitsuba, numpy, matplotlib) and Debian's LLVM 19 for Mitsuba's
# llvm_ad_rgb variant, builds kdtrace, then runs the benchmark. Results: bench/results/.
# Extra arguments go to time_vs_error.py (e.g. --scenes cornell-box --ref-spp 1024).
set -euo pipefail
cd "$(dirname "$0")/.."
SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO=sudo
LLVM=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1
if [ ! -e "$LLVM" ]; then
    $SUDO apt-get update && $SUDO apt-get install -y libllvm19
fi
if [ ! -x bench/.venv/bin/python ]; then
    python3 -m venv bench/.venv
fi
bench/.venv/bin/python -m pip install -q bpy==5.0.1 mitsuba numpy matplotlib
export DRJIT_LIBLLVM_PATH=$LLVM
cargo build --release -p kdtrace
exec bench/.venv/bin/python bench/time_vs_error.py "$@"
