#!/usr/bin/env bash
# Regenerates tests/data/cornell-box-mitsuba-32{,-stderr}.exr, or with `metal`, `glass`,
# `smooth-glass`, `plastic`, `roughplastic`, `textured` or `environment` the references of the tall block's materials and of the
# textured box (see make_test_reference.py for where each goes), with
# the venv and LLVM that bench/peers.sh sets up. About 2-4 minutes on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/../.."
export DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1
exec bench/.venv/bin/python bench/peers/make_test_reference.py "$@"
