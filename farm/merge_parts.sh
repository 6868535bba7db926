#!/usr/bin/env bash
# The merge step of the Slurm and Kubernetes recipes: checks that all TASKS parts are in
# PARTS_DIR (naming the missing ones), then `kdtrace merge`s them into OUT, which is the image
# one `kdtrace render` of the same settings writes, bit for bit.
#   farm/merge_parts.sh
# Environment: PARTS_DIR, TASKS, OUT (.exr or .png); optional VARIANCE (an .exr for the
# per-pixel variance), KDTRACE (default: kdtrace on PATH).
set -euo pipefail
: "${PARTS_DIR:?PARTS_DIR must name the folder of the parts}" "${TASKS:?TASKS must be set}"
: "${OUT:?OUT must name the merged image}"
parts=() missing=()
for ((i = 0; i < TASKS; i++)); do
  p=$(printf '%s/part-%05d.kdp' "$PARTS_DIR" "$i")
  if [ -f "$p" ]; then parts+=("$p"); else missing+=("$i"); fi
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "merge_parts.sh: ${#missing[@]} of $TASKS parts missing from $PARTS_DIR (task indexes ${missing[*]}); rerun those tasks" >&2
  exit 1
fi
variance=()
if [ -n "${VARIANCE:-}" ]; then variance=(--variance "$VARIANCE"); fi
"${KDTRACE:-kdtrace}" merge "${parts[@]}" --out "$OUT" "${variance[@]}"
echo "merge_parts.sh: merged $TASKS parts from $PARTS_DIR into $OUT" >&2
