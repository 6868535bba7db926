#!/usr/bin/env bash
# The numerical stress suite at bench size: 10^7 rays per configuration (watertightness from
# inside a closed mesh at scales 1e-4..1e6 and 1e5 away; spawned-ray self-intersection; f32 vs
# f64 reference). The test suite runs the same checks with 10^6. Usage: bench/stress.sh [RAYS]
set -euo pipefail
cd "$(dirname "$0")/.."
STRESS_RAYS=${1:-10000000} cargo test --release -p kdtrace --test stress_numerics -- --nocapture 2>&1 | grep -E "scale|f64 reference|test result"
