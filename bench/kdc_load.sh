#!/usr/bin/env bash
# Load time of a compiled .kdc scene against parsing the OBJ and building its k-d tree, with the
# release binary, median of RUNS runs each (warm page cache: every file is read once before
# timing). Prints a Markdown table for BENCHMARKS.md.
# Usage: bench/kdc_load.sh [SCENE.obj|SCENE.toml] [RUNS]     (run scripts/setup.sh first)
set -euo pipefail
cd "$(dirname "$0")/.."
scene=${1:-../shared/scenes/conference-geometry/conference.obj}
runs=${2:-5}
cargo build --release -q
bin=target/release/kdtrace
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
compiled=$("$bin" compile "$scene" --out "$out/scene.kdc" --json)
one_pixel=(--out "$out/x.png" --width 1 --height 1 --spp 1 --bounces 0 --json)
"$bin" render "$scene" "${one_pixel[@]}" >/dev/null 2>&1   # warm the page cache
"$bin" render "$out/scene.kdc" "${one_pixel[@]}" >/dev/null
for _ in $(seq "$runs"); do "$bin" render "$scene" "${one_pixel[@]}" 2>/dev/null; done >"$out/source.jsonl"
for _ in $(seq "$runs"); do "$bin" render "$out/scene.kdc" "${one_pixel[@]}" 2>/dev/null; done >"$out/kdc.jsonl"
python3 - "$out" "$compiled" <<'PY'
import json, statistics, sys
out, compiled = sys.argv[1], json.loads(sys.argv[2])
src = [json.loads(l) for l in open(out + "/source.jsonl")]
kdc = [json.loads(l) for l in open(out + "/kdc.jsonl")]
parse = statistics.median(j["load_s"] for j in src)
# The .kdc's load_s includes laying the scene out for rendering, which an OBJ's prepare_s counts.
build = statistics.median(j["build_s"] + j.get("prepare_s", 0.0) for j in src)
both = statistics.median(j["load_s"] + j["build_s"] + j.get("prepare_s", 0.0) for j in src)
load = statistics.median(j["load_s"] for j in kdc)
print("| scene | triangles | nodes | .kdc MB | parse s | build s | parse + build s | .kdc load s | speed-up |")
print("|---|---|---|---|---|---|---|---|---|")
print("| %s | %d | %d | %.1f | %.3f | %.3f | %.3f | %.4f | %.0fx |" % (
    compiled["scene"], compiled["triangles"], compiled["nodes"], compiled["bytes"] / 1e6, parse, build, both, load, both / load))
print("\nruns: %d each; parse+build per run: %s; .kdc load per run: %s" % (
    len(src), ", ".join("%.3f" % (j["load_s"] + j["build_s"] + j.get("prepare_s", 0.0)) for j in src), ", ".join("%.4f" % j["load_s"] for j in kdc)))
PY
