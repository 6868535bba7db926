#!/usr/bin/env bash
# The Cornell box (CornellBox-Original) scaled by powers of ten, camera scaled with it, rendered
# at 32x32, 64 spp, 4 bounces, the same seed, and compared with the unscaled render: the mean
# ratio and relMSE show where f32 arithmetic stops rendering the same scene (BENCHMARKS.md,
# "Numerical stress"). Scales outside the renderable range are refused (exit 2), which is shown.
# Usage: bench/scales.sh [SCALE ...]     (run scripts/setup.sh first)
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -q
bin=$PWD/target/release/kdtrace
mesh=$PWD/tests/data/meshes/CornellBox-Original/CornellBox-Original.obj
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
scales=("$@")
[ ${#scales[@]} -gt 0 ] || scales=(1e-12 1e-10 1e-8 1e-4 1e4 1e8 1e10 1e12 2e12 1e13)
render() {
  python3 - "$1" "$mesh" >"$out/s.toml" <<'PY'
import sys
s, mesh = float(sys.argv[1]), sys.argv[2]
print(f"[camera]\nwidth = 32\nheight = 32\neye = [0, {s!r}, {3.4 * s!r}]\ntarget = [0, {s!r}, 0]\nfov = 39.3")
print(f"[render]\nspp = 64\nbounces = 4\n[[mesh]]\nfile = {mesh!r}\nscale = {s!r}")
PY
  "$bin" render "$out/s.toml" --out "$out/$1.exr" 2>"$out/err" || { echo "| $1 | refused: $(tail -1 "$out/err" | cut -c1-120) |"; return; }
  "$bin" compare "$out/1.exr" "$out/$1.exr" --json | python3 -c \
    "import json,sys; j=json.load(sys.stdin); print('| $1 | mean ratio %.6f, relMSE %.2e |' % (j['mean_ratio'], j['relmse']))"
}
render 1 >/dev/null
echo "| scale | against scale 1 |"
echo "|---|---|"
for s in "${scales[@]}"; do render "$s"; done
