#!/usr/bin/env bash
# Speed of the CPU reference and the GPU kernel on the same scene, side by side in one run, and
# their agreement (kdtrace verify). Prints a Markdown table for BENCHMARKS.md.
# Usage: bench/spine.sh [SCENE.obj] [SIZE] [SPP]     (run scripts/setup.sh first)
set -euo pipefail
cd "$(dirname "$0")/.."
scene=${1:-scenes/cornell-box.obj}
size=${2:-256}
spp=${3:-16}
cargo build --release -q
bin=target/release/kdtrace
out=$(mktemp -d)
row='import json,sys
j = json.loads(sys.stdin.read())
print("| %s | %s | %s | %d | %dx%d | %d | %d | %.3f | %.3f |" % (j["device"], j["adapter"], j["scene"], j["triangles"], j["width"], j["height"], j["spp"], j["bounces"], j["render_s"], j["samples_per_s"] / 1e6))'
echo "| device | adapter | scene | triangles | image | spp | bounces | render s | Msamples/s |"
echo "|---|---|---|---|---|---|---|---|---|"
for device in cpu gpu; do
  # The first GPU run compiles the shader into Mesa's cache; time the second.
  [ "$device" = gpu ] && $bin render "$scene" --out "$out/warm.png" --device gpu --spp 1 --width 8 --height 8 --json >/dev/null 2>&1
  $bin render "$scene" --out "$out/$device.png" --device $device --spp "$spp" --width "$size" --height "$size" --json 2>/dev/null |
    python3 -c "$row"
done
echo
$bin verify "$scene" --spp 16 --width 64 --height 64 2>/dev/null
