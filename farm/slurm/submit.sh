#!/usr/bin/env bash
# Submits a farm render to Slurm: a job array of TASKS tasks (index i renders task i's sample
# range into PARTS_DIR) and a merge job that runs after all of them succeeded.
#   farm/slurm/submit.sh SCENE SPP TASKS OUT PARTS_DIR [kdtrace render flags...] [-- sbatch options...]
# e.g.
#   farm/slurm/submit.sh /shared/box.kdc 4096 64 /shared/box.exr /shared/box-parts \
#     --width 1920 --height 1080 --bounces 6 -- --partition=render --cpus-per-task=32
# SCENE, OUT, PARTS_DIR, this repository and KDTRACE (default: kdtrace on PATH of the nodes)
# must be on storage every node sees, at the same paths.
set -euo pipefail
if [ $# -lt 5 ]; then
  sed -n '2,9p' "$0" >&2
  exit 2
fi
farm=$(cd "$(dirname "$0")/.." && pwd)
scene=$(realpath "$1") spp=$2 tasks=$3 out=$(realpath -m "$4") parts=$(realpath -m "$5")
shift 5
render_args=() sbatch_args=()
while [ $# -gt 0 ]; do
  if [ "$1" = "--" ]; then shift; sbatch_args=("$@"); break; fi
  render_args+=("$1"); shift
done
python3 "$farm/ranges.py" --spp "$spp" --tasks "$tasks" >/dev/null # refuses a bad SPP/TASKS now
mkdir -p "$parts"
# Slurm's --export splits on commas, so RENDER_ARGS (no commas allowed there) travels in the
# environment instead: --export=ALL passes this shell's variables.
export FARM_DIR="$farm" SCENE="$scene" SPP="$spp" TASKS="$tasks" PARTS_DIR="$parts" OUT="$out"
RENDER_ARGS="${render_args[*]}"
export RENDER_ARGS
array=$(sbatch --parsable --export=ALL --array="0-$((tasks - 1))" "${sbatch_args[@]}" "$farm/slurm/render.sbatch")
array=${array%%;*}
merge=$(sbatch --parsable --export=ALL --dependency="afterok:$array" "$farm/slurm/merge.sbatch")
echo "submitted: render array $array (tasks 0-$((tasks - 1))), merge job $merge -> $out"
