#!/usr/bin/env bash
# Renders the material pictures of BENCHMARKS.md ("Materials") into bench/renders/materials.png:
# CornellBox-Glossy, -Mirror, -Sphere and -Water from ../shared/scenes with their MTL materials,
# and the Cornell box with a rough gold, a rough glass and a plastic tall block
# (tests/data/cornell-{metal,materials}), 256×256 at 256 spp on the CPU, tiled 4 + 3; and the
# textured Sponza (../shared/scenes/sponza-dabrovic-mitsuba, its MTL's JPEG textures) under a
# sky of 3 into bench/renders/sponza-textured.png. Needs the bench venv (bench/peers.sh) for the
# tiling. Prints each render's time.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -q
out=bench/results/materials
mkdir -p "$out"
k=./target/release/kdtrace
common=(--width 256 --height 256 --spp 256 --bounces 8)
for s in Glossy Mirror Sphere Water; do
  $k render "../shared/scenes/CornellBox-$s/CornellBox-$s.obj" "${common[@]}" \
    --eye 0,1,3.4 --target 0,1,0 --fov 39.3 --out "$out/$s.png"
done
for s in cornell-metal/cornell-metal cornell-materials/cornell-glass cornell-materials/cornell-plastic; do
  $k render "tests/data/$s.toml" "${common[@]}" --out "$out/$(basename "$s").png"
done
$k render ../shared/scenes/sponza-dabrovic-mitsuba/sponza.obj --width 480 --height 320 --spp 64 \
  --bounces 6 --eye=-11,3,0 --target=11,5,0 --fov 60 --environment 3,3,3 --out bench/renders/sponza-textured.png
bench/.venv/bin/python - "$out" <<'PY'
import sys
import numpy as np
from PIL import Image
d = sys.argv[1]
names = ["Glossy", "Mirror", "Sphere", "Water", "cornell-metal", "cornell-glass", "cornell-plastic"]
tiles = [np.asarray(Image.open(f"{d}/{n}.png").convert("RGB")) for n in names]
blank = np.zeros_like(tiles[0])
rows = [np.concatenate(tiles[:4], axis=1), np.concatenate(tiles[4:] + [blank], axis=1)]
Image.fromarray(np.concatenate(rows, axis=0)).save("bench/renders/materials.png")
PY
