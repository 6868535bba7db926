#!/usr/bin/env bash
# One task of a farm render: renders task INDEX's sample range (farm/ranges.py) into
# $PARTS_DIR/part-INDEX.kdp (index zero-padded to 5 digits). The Slurm job array
# (farm/slurm/render.sbatch) and the Kubernetes Indexed Job (farm/k8s/render-job.yaml) run it.
#   farm/render_range.sh INDEX
# Environment:
#   SCENE        the scene file (on storage every node reads)
#   SPP, TASKS   samples per pixel of the whole image, and the number of tasks K
#   PARTS_DIR    where the parts go (storage every node writes and the merge step reads)
#   RENDER_ARGS  further `kdtrace render` flags, the same for every task, split on spaces:
#                e.g. "--width 1920 --height 1080 --bounces 6 --seed 0 --eye 0,1,3.5"
#   KDTRACE      the kdtrace binary (default: kdtrace on PATH)
#   PYTHON       a Python 3 for farm/ranges.py (default: python3)
set -euo pipefail
farm=$(cd "$(dirname "$0")" && pwd)
index=${1:?usage: farm/render_range.sh INDEX}
: "${SCENE:?SCENE must name the scene file}" "${SPP:?SPP must be set}" "${TASKS:?TASKS must be set}"
: "${PARTS_DIR:?PARTS_DIR must name the folder for the parts}"
kdtrace=${KDTRACE:-kdtrace}
range=$("${PYTHON:-python3}" "$farm/ranges.py" --spp "$SPP" --tasks "$TASKS" --index "$index")
if [ ! -f "$SCENE" ]; then
  echo "render_range.sh: the scene $SCENE does not exist on $(hostname)" >&2
  exit 1
fi
mkdir -p "$PARTS_DIR"
name=$(printf 'part-%05d.kdp' "$index")
# Written under another name and renamed when complete, so that a task killed mid-write leaves
# no part-*.kdp for the merge to pick up; a retry of the task overwrites the part.
tmp="$PARTS_DIR/incomplete-$(printf '%05d' "$index")-$$.kdp"
echo "render_range.sh: task $index of $TASKS: samples $range of $SCENE on $(hostname)" >&2
# shellcheck disable=SC2086 # RENDER_ARGS is a list of flags
"$kdtrace" render "$SCENE" --samples "$range" --partial "$tmp" ${RENDER_ARGS:-}
mv -f "$tmp" "$PARTS_DIR/$name"
