#!/usr/bin/env bash
# Ray-casting throughput (kdtrace rays): the Aila & Laine triple (primary, ambient occlusion,
# diffuse) on the CPU path (its wide BVH and the k-d tree) and the GPU kernel, with the short and
# the full k-d traversal stack, and
# the persistent-threads vs one-invocation-per-pixel render on the GPU. Side by side in one run;
# prints Markdown tables for BENCHMARKS.md.
# Usage: bench/rays.sh [SHARED_SCENES_DIR] [SIZE]   (run scripts/setup.sh first)
set -euo pipefail
cd "$(dirname "$0")/.."
scenes=${1:-../shared/scenes}
size=${2:-512}
cargo build --release -q
bin=target/release/kdtrace
row='import json,sys
for line in sys.stdin:
    j = json.loads(line)
    ideal = "%.2f" % j["ideal_mrays_per_s"]
    ratio = "%.2f" % j["measured_over_ideal"]
    print("| %s | %s | %s | %s | %d | %.2f | %.1f | %.1f | %.3f | %s | %s |" % (j["scene"].split("/")[-1], j["adapter"].split(" (")[0], j["traversal"], j["kind"], j["rays"], j["mrays_per_s"], j["nodes_per_ray"], j["tests_per_ray"], j["restarts_per_ray"], ideal, ratio))'
echo "| scene | device | stack | rays | count | Mrays/s | nodes/ray | tests/ray | restarts/ray | ideal Mrays/s | measured/ideal |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
# Cameras: the bunny framed from outside; Sponza and the conference room from inside, so that
# ambient-occlusion and diffuse rays bounce around the interior.
camera() {
  case "$1" in
    sponza*) echo "--eye -13,3,0 --target 10,5,0 --up 0,1,0 --fov 60" ;;
    conference*) echo "--eye 1300,250,300 --target -500,150,-500 --up 0,1,0 --fov 60" ;;
    *) echo "" ;;
  esac
}
for mesh in bunny-stanford-bun_zipper/bun_zipper.obj sponza-dabrovic/sponza.obj conference-geometry/conference.obj; do
  path="$scenes/$mesh"
  [ -f "$path" ] || { echo "missing $path" >&2; continue; }
  for device in cpu gpu; do
    stacks="short full"
    [ $device = cpu ] && stacks="wide short full"
    for stack in $stacks; do
      # shellcheck disable=SC2046
      $bin rays "$path" --device $device --traversal $stack --width "$size" --height "$size" $(camera "$mesh") --json 2>/dev/null | python3 -c "$row"
    done
  done
done
echo
echo "| scene | dispatch | stack | render s (GPU, ${size}², 4 spp, 6 bounces) |"
echo "|---|---|---|---|"
out=$(mktemp -d)
for mesh in bunny-stanford-bun_zipper/bun_zipper.obj sponza-dabrovic/sponza.obj; do
  path="$scenes/$mesh"
  [ -f "$path" ] || continue
  # Warm Mesa's shader cache for both kernels: the first use of a pipeline compiles it.
  for dispatch in plain persistent; do
    $bin render "$path" --out "$out/warm.png" --device gpu --dispatch $dispatch --spp 1 --width 8 --height 8 >/dev/null 2>&1
  done
  for dispatch in plain persistent; do
    for stack in short full; do
      # shellcheck disable=SC2046
      s=$($bin render "$path" --out "$out/x.png" --device gpu --dispatch $dispatch --traversal $stack --spp 4 --width "$size" --height "$size" $(camera "$mesh") --json 2>/dev/null | python3 -c 'import json,sys; print("%.3f" % json.loads(sys.stdin.read())["render_s"])')
      echo "| ${mesh%%/*} | $dispatch | $stack | $s |"
    done
  done
done
