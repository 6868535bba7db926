#!/usr/bin/env bash
# Renders the glTF pictures of the README ("glTF 2.0 scenes") into bench/renders/gltf-environment.png:
# Khronos' ToyCar, TransmissionTest and MetalRoughSpheresNoTextures (../shared/scenes/gltf-*, each
# file's own camera) under the procedural daylight sky of make_sky.py, 480×360 at 256 spp, 8
# bounces, on the CPU, side by side. Needs the bench venv (bench/peers.sh) for the tiling. Prints
# each render's time.
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release -q
[ -f bench/gltf/sky.pfm ] || python3 bench/gltf/make_sky.py
out=bench/results/gltf
mkdir -p "$out"
for s in ToyCar TransmissionTest MetalRoughSpheresNoTextures; do
  ./target/release/kdtrace render "../shared/scenes/gltf-$s/$s.gltf" --width 480 --height 360 --spp 256 \
    --bounces 8 --environment bench/gltf/sky.pfm --out "$out/$s.png"
done
bench/.venv/bin/python - "$out" <<'PY'
import sys
from PIL import Image
d = sys.argv[1]
tiles = [Image.open(f"{d}/{s}.png").convert("RGB") for s in ["ToyCar", "TransmissionTest", "MetalRoughSpheresNoTextures"]]
strip = Image.new("RGB", (sum(t.width for t in tiles), max(t.height for t in tiles)))
x = 0
for t in tiles:
    strip.paste(t, (x, 0))
    x += t.width
strip.save("bench/renders/gltf-environment.png")
PY
echo bench/renders/gltf-environment.png
