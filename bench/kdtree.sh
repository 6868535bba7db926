#!/usr/bin/env bash
# k-d tree build speed and quality on the public meshes, side by side in one run: the SAH builder
# on one thread and on all threads, for the CPU's tree (the default) and the GPU's, and the
# spatial-median baseline. Prints a Markdown table
# for BENCHMARKS.md. Usage: bench/kdtree.sh [SHARED_SCENES_DIR]   (run scripts/setup.sh first)
set -euo pipefail
cd "$(dirname "$0")/.."
scenes=${1:-../shared/scenes}
cargo build --release -q
bin=target/release/kdtrace
row='import json,sys
j = json.loads(sys.stdin.read())
b = j["builder"] if j["builder"] != "sah" else "sah, K_I %g per %d" % (j["settings"]["intersection_cost"], j["settings"]["leaf_block"])
print("| %s | %d | %s | %d | %d | %d | %d | %d | %.2f | %.1f | %.3f | %.3f | %.3f |" % (j["scene"].split("/")[-1], j["triangles"], b, j["threads"], j["nodes"], j["empty_leaves"], j["max_depth"], j["total_refs"], j["mean_leaf_refs"], j["sah_cost"], j["build_s"], j["mtris_per_s"], j["prepare_s"]))'
# build s: the k-d tree (kdbuild::build); prepare s: laying the scene out for rendering after it
# (unit normals, the CPU's leaf blocks), which a .kdc load also does.
echo "| scene | triangles | builder | threads | nodes | empty leaves | depth | refs | refs/leaf | SAH cost | build s | Mtris/s | prepare s |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|"
for mesh in bunny-stanford-bun_zipper/bun_zipper.obj dragon-100k/dragon.obj happy-buddha-100k/buddha.obj sponza-dabrovic/sponza.obj conference-geometry/conference.obj; do
  path="$scenes/$mesh"
  [ -f "$path" ] || { echo "missing $path" >&2; continue; }
  RAYON_NUM_THREADS=1 $bin tree "$path" --json 2>/dev/null | python3 -c "$row"
  $bin tree "$path" --json 2>/dev/null | python3 -c "$row"
  # The GPU's tree (kdbuild::BuildSettings::for_gpu: per-triangle leaf cost, Wald & Havran's K_I).
  RAYON_NUM_THREADS=1 $bin tree "$path" --leaf-block 1 --intersection-cost 20 --json 2>/dev/null | python3 -c "$row"
  $bin tree "$path" --leaf-block 1 --intersection-cost 20 --json 2>/dev/null | python3 -c "$row"
  $bin tree "$path" --builder median --json 2>/dev/null | python3 -c "$row"
done
# Every public mesh's tree passes `validate` (the tests check the meshes copied into tests/data).
echo
status=0
for path in "$scenes"/*/*.obj; do
  if ! $bin tree "$path" --validate >/dev/null 2>&1; then echo "INVALID TREE: $path"; status=1; fi
done
[ $status -eq 0 ] && echo "every tree of $scenes/*/*.obj passes validate"
exit $status
