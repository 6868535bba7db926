#!/usr/bin/env bash
# The inputs of the farm scaling model (farm/scaling.py), measured on this machine for one
# scene, and local Ray runs of 1, 2 and 4 worker nodes as a check of the model at small N:
#   - per-sample time: seconds per sample per pixel of the whole image, with one thread (a Ray
#     worker node of farm/local_cluster.sh has one CPU) and with all threads;
#   - start-up per task: a 1×1-pixel, 1-sample render's wall time (process start, scene parse
#     and k-d build, or the .kdc load; with DEVICE=gpu also the kernel compile), and its parts
#     (load_s, build_s, prepare_s) for the scene file and for its .kdc; plus Ray's dispatch per
#     task (the first Ray run's wall time less connecting and the ranges' renders, per task);
#   - the partial file's size at WIDTH×HEIGHT, and the merge's speed (TASKS parts);
#   - `farm/ray_render.py` on a local cluster of W one-CPU worker nodes for W in WORKERS, inside
#     a network namespace of its own (farm/local_cluster.sh; needs root for unshare).
# Writes bench/results/farm-scaling-DATE/results.json and prints the model's table for
# 1 … 1,000 nodes (farm/scaling.py --measured). Keep SPP × WIDTH × HEIGHT small for a quick
# check; the figures for BENCHMARKS.md want a real scene and size.
#   [SPP=64 WIDTH=128 HEIGHT=128 BOUNCES=6 TASKS=8 WORKERS="1 2 4" DEVICE=cpu] bench/farm_scaling.sh [SCENE]
set -euo pipefail
cd "$(dirname "$0")/.."
scene=$(realpath "${1:-scenes/cornell-box.toml}")
spp=${SPP:-64} width=${WIDTH:-128} height=${HEIGHT:-128} bounces=${BOUNCES:-6}
tasks=${TASKS:-8} workers=${WORKERS:-1 2 4} device=${DEVICE:-cpu}
if [ ! -f "$scene" ]; then
  echo "farm_scaling.sh: the scene $scene does not exist" >&2
  exit 1
fi
cargo build --release -q
farm/setup.sh
bin=$PWD/target/release/kdtrace
py=$PWD/farm/.venv/bin/python
out=$PWD/bench/results/farm-scaling-$(date -u +%Y%m%d-%H%M%S)
mkdir -p "$out"
size=(--width "$width" --height "$height" --bounces "$bounces")
echo "farm_scaling.sh: $scene, $spp spp at ${width}x$height, results in $out" >&2

# Per-sample time, one thread and all threads.
RAYON_NUM_THREADS=1 "$bin" render "$scene" --spp "$spp" "${size[@]}" --device "$device" --out "$out/single.exr" --json \
  >"$out/render-1-thread.json"
"$bin" render "$scene" --spp "$spp" "${size[@]}" --device "$device" --out "$out/single.exr" --json >"$out/render-all-threads.json"

# Start-up: a render that is nearly all start-up, of the scene file and of its .kdc (timed with
# its process start).
"$bin" compile "$scene" --out "$out/scene.kdc" --json >"$out/compile.json" || echo '{}' >"$out/compile.json"
startup() { # NAME SCENE
  "$py" - "$bin" "$2" "$device" "$out/startup-$1.json" <<'PY'
import json, subprocess, sys, time
bin, scene, device, dest = sys.argv[1:]
runs = []
for _ in range(3):
    t = time.perf_counter()
    p = subprocess.run([bin, "render", scene, "--spp", "1", "--width", "1", "--height", "1", "--device", device,
                        "--out", dest + ".exr", "--json"], capture_output=True, text=True, check=True)
    runs.append(dict(json.loads(p.stdout), wall_s=time.perf_counter() - t))
json.dump(min(runs, key=lambda r: r["wall_s"]), open(dest, "w"))
PY
}
startup scene "$scene"
if [ -s "$out/scene.kdc" ]; then startup kdc "$out/scene.kdc"; fi
rm -f "$out"/startup-*.exr

# Partial files: TASKS ranges at the full size, their bytes, and the merge's time.
mapfile -t ranges < <(python3 farm/ranges.py --spp "$spp" --tasks "$tasks")
parts=()
for i in "${!ranges[@]}"; do
  p=$(printf '%s/part-%05d.kdp' "$out" "$i")
  "$bin" render "$scene" --samples "${ranges[$i]}" --partial "$p" "${size[@]}" --device "$device" >/dev/null 2>&1
  parts+=("$p")
done
"$py" - "$bin" "$out" "${parts[@]}" <<'PY'
import json, os, subprocess, sys, time
bin, out, parts = sys.argv[1], sys.argv[2], sys.argv[3:]
t = time.perf_counter()
subprocess.run([bin, "merge", *parts, "--out", os.path.join(out, "merged.exr")], check=True, capture_output=True)
merge_s = time.perf_counter() - t
same = open(os.path.join(out, "merged.exr"), "rb").read() == open(os.path.join(out, "single.exr"), "rb").read()
json.dump({"parts": len(parts), "part_bytes": os.path.getsize(parts[0]), "merge_s": merge_s,
           "merged_equals_single": same}, open(os.path.join(out, "merge.json"), "w"))
PY
rm -f "$out"/part-*.kdp

# Local Ray clusters of W one-CPU worker nodes.
for w in $workers; do
  echo "farm_scaling.sh: Ray, $w worker node(s)" >&2
  cluster=$(mktemp -d /tmp/kdray-XXXXXX) # short: Ray's socket paths live under it
  if ! unshare --net --pid --fork --mount-proc bash -c '
    set -euo pipefail
    ip link set lo up
    farm/local_cluster.sh "${10}" "$2" 1
    RAY_AUTH_MODE=disabled farm/.venv/bin/python farm/ray_render.py "$3" --spp "$4" --tasks "$5" --address 127.0.0.1:6379 --json \
      --kdtrace "$6" --out "$1/ray-$2.exr" --width "$7" --height "$8" --bounces "$9" | tail -n 1 >"$1/ray-$2.json"
  ' bash "$out" "$w" "$scene" "$spp" "$tasks" "$bin" "$width" "$height" "$bounces" "$cluster" 2>"$out/ray-$w.log"; then
    echo "farm_scaling.sh: the Ray run with $w worker(s) failed; the end of $out/ray-$w.log:" >&2
    grep -v network_util "$out/ray-$w.log" | tail -n 15 >&2
    rm -rf "$cluster"
    exit 1
  fi
  rm -rf "$cluster"
done

"$py" - "$out" "$spp" "$workers" <<'PY'
import json, os, sys
out, spp, workers = sys.argv[1], int(sys.argv[2]), sys.argv[3].split()
load = lambda name: json.load(open(os.path.join(out, name)))
one, allt = load("render-1-thread.json"), load("render-all-threads.json")
start = load("startup-scene.json")
kdc = load("startup-kdc.json") if os.path.exists(os.path.join(out, "startup-kdc.json")) else None
merge = load("merge.json")
ray = {w: load(f"ray-{w}.json") for w in workers}
# Ray's cost per task beyond kdtrace's own run (render_s, process start included): in the first
# run, each of its W workers ran tasks/W ranges one after another in the wall time less connecting.
r0, w0 = ray[workers[0]], int(workers[0])
busy = r0["render_wall_s"] - r0["connect_s"]
dispatch = max(0.0, (busy - sum(r["render_s"] for r in r0["ranges"]) / w0) / (r0["tasks"] / w0))
res = {
    "scene": one["scene"], "width": one["width"], "height": one["height"], "spp": spp, "device": one["device"],
    "t_sample_1_thread_s": one["render_s"] / spp, "t_sample_all_threads_s": allt["render_s"] / spp,
    "threads": allt["adapter"],
    "startup_scene": {k: start[k] for k in ("wall_s", "load_s", "build_s", "prepare_s")},
    "startup_kdc": {k: kdc[k] for k in ("wall_s", "load_s", "build_s", "prepare_s")} if kdc else None,
    "merge": merge,
    "ray": {w: {"connect_s": r["connect_s"], "render_wall_s": r["render_wall_s"], "merge_s": r["merge_s"],
                "retries": r["retries"], "part_bytes": r["part_bytes"]} for w, r in ray.items()},
    "ray_dispatch_per_task_s": dispatch,
    # The model's inputs: one-CPU nodes, as in the local runs.
    # start: the process's start-up and Ray's dispatch of its task.
    "model_inputs": {"spp": spp, "t_sample_s": one["render_s"] / spp, "start_s": start["wall_s"] + dispatch,
                     "part_bytes": merge["part_bytes"],
                     "merge_bytes_per_s": merge["part_bytes"] * merge["parts"] / merge["merge_s"]},
}
json.dump(res, open(os.path.join(out, "results.json"), "w"), indent=1)
print(f"per sample: {res['t_sample_1_thread_s']:.4g} s (1 thread), {res['t_sample_all_threads_s']:.4g} s ({res['threads']})")
print(f"start-up: {start['wall_s']:.3f} s (load {start['load_s']:.3f}, build {start['build_s']:.3f}, prepare {start['prepare_s']:.3f})"
      + (f"; from the .kdc {kdc['wall_s']:.3f} s" if kdc else ""))
print(f"part: {merge['part_bytes']} bytes; merge of {merge['parts']} parts {merge['merge_s']:.3f} s; "
      f"merged = single render: {merge['merged_equals_single']}")
print(f"Ray: {dispatch:.3f} s per task beyond kdtrace's own run (from the {workers[0]}-worker run)")
base = ray[workers[0]]["render_wall_s"]
sys.path.insert(0, "farm")
import scaling  # noqa: E402
m = res["model_inputs"]
cores = os.cpu_count()
for w in workers:
    r = ray[w]
    predicted = scaling.model(spp, m["t_sample_s"], m["start_s"], m["part_bytes"], 10e9 / 8, 1 / m["merge_bytes_per_s"],
                              int(w), tasks=r["tasks"], cores=cores)
    print(f"Ray, {w} worker node(s): {r['render_wall_s']:.2f} s + merge {r['merge_s']:.2f} s "
          f"(speed-up {base / r['render_wall_s']:.2f} against {workers[0]}); the model, {r['tasks']} tasks on "
          f"{min(int(w), cores)} of {cores} cores: {predicted:.2f} s")
PY
python3 farm/scaling.py --measured "$out/results.json"
