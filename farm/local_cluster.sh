#!/usr/bin/env bash
# Starts a Ray cluster of "machines" on this one: a head (no CPUs, so no range runs there) at
# 127.0.0.1:6379 and WORKERS worker nodes at 127.0.0.2, 127.0.0.3, ..., each with CPUS CPUs,
# its own temporary folder under DIR, and in a PID namespace of its own, so that killing the
# pid in DIR/worker-N.pid (its `unshare --kill-child`) ends every process of that node at once,
# as a machine failing would. Returns once all nodes have joined (at most 60 s).
#
# Run it inside a network namespace of its own, where only loopback exists, so that no Ray port
# is reachable from outside and every Ray process ends with the namespace (needs root):
#   unshare --net --pid --fork --mount-proc bash -c \
#     'ip link set lo up && farm/local_cluster.sh /tmp/kdray 2 &&
#      RAY_AUTH_MODE=disabled farm/.venv/bin/python farm/ray_render.py ... --address 127.0.0.1:6379'
# Used by tests/farm.rs and bench/farm_scaling.sh.
#   farm/local_cluster.sh DIR WORKERS [CPUS]
set -euo pipefail
if [ $# -lt 2 ]; then
  echo "usage: farm/local_cluster.sh DIR WORKERS [CPUS]" >&2
  exit 2
fi
farm=$(cd "$(dirname "$0")" && pwd)
ray="$farm/.venv/bin/ray"
python="$farm/.venv/bin/python"
dir=$1 workers=$2 cpus=${3:-1}
if [ ! -x "$ray" ]; then
  echo "farm/local_cluster.sh: $ray is missing: run farm/setup.sh first" >&2
  exit 1
fi
# Ray's socket paths (DIR/worker-N/session_.../sockets/plasma_store) must fit in 107 bytes.
if [ ${#dir} -gt 40 ]; then
  echo "farm/local_cluster.sh: DIR $dir is too long for Ray's socket paths (at most 40 characters; e.g. /tmp/kdray)" >&2
  exit 2
fi
mkdir -p "$dir"
export RAY_USAGE_STATS_ENABLED=0
# No token authentication: this cluster is reachable on loopback only, inside its network
# namespace. (Explicitly: Ray turns token authentication on by itself where ~/.ray/auth_token
# exists, which a local `ray.init()` writes.) The driver run against it needs the same setting.
export RAY_AUTH_MODE=disabled
common=(--object-store-memory 100000000 --disable-usage-stats)
if ! "$ray" start --head --node-ip-address 127.0.0.1 --port 6379 --num-cpus 0 --include-dashboard false \
  --temp-dir "$dir/head" "${common[@]}" >"$dir/head.log" 2>&1; then
  echo "farm/local_cluster.sh: the head did not start; its log, $dir/head.log:" >&2
  tail -n 20 "$dir/head.log" >&2
  exit 1
fi
for i in $(seq 1 "$workers"); do
  unshare --pid --fork --kill-child --mount-proc \
    "$ray" start --address 127.0.0.1:6379 --node-ip-address "127.0.0.$((i + 1))" --num-cpus "$cpus" \
    --temp-dir "$dir/worker-$i" "${common[@]}" --block >"$dir/worker-$i.log" 2>&1 &
  echo $! >"$dir/worker-$i.pid"
done
"$python" - "$((workers + 1))" <<'PY'
import sys, time, ray
want = int(sys.argv[1])
ray.init(address="127.0.0.1:6379", logging_level="WARNING", log_to_driver=False)
deadline = time.time() + 60
while sum(n["Alive"] for n in ray.nodes()) < want:
    if time.time() > deadline:
        sys.exit(f"farm/local_cluster.sh: only {sum(n['Alive'] for n in ray.nodes())} of {want} nodes joined in 60 s")
    time.sleep(0.2)
PY
echo "farm/local_cluster.sh: head 127.0.0.1:6379 and $workers worker(s) of $cpus CPU(s) up" >&2
