#!/usr/bin/env python3
"""Render one image on a Ray cluster: the samples are cut into K ranges (farm/ranges.py), each
range is one Ray task that runs `kdtrace render --samples A..B --partial` on a worker node, and
the driver merges the parts with `kdtrace merge` into the image a single `kdtrace render` of the
same settings would write, bit for bit.

    farm/setup.sh                                  # makes farm/.venv with the pinned Ray
    farm/.venv/bin/python farm/ray_render.py scenes/cornell-box.toml --spp 1024 --tasks 32 \\
        --out box.exr --address HEAD:6379 --width 1280 --height 720

How the binary and the scene reach the workers (farm/README.md):
  - by default, by path: KDTRACE (--kdtrace) and SCENE must exist at the same absolute paths on
    every node (a shared file system, or the same container image);
  - with --ship, through Ray's object store: the driver puts the binary and the scene file into
    it once, and each node writes them into a cache folder under its temporary directory. Only
    the one scene file travels, so a scene with companion files (an .obj's .mtl, textures, the
    meshes a .toml names) must be compiled into one .kdc first (`kdtrace compile`).

Failures: a task whose worker process or node dies, or whose kdtrace is killed by a signal, is
run again by Ray (--max-retries) on a node that is alive; the driver prints each start, each
retry and each finished range, and with --json one JSON report on stdout. A range whose kdtrace
exits with an error (bad scene, bad flags) is not retried: the same command would fail again;
the driver stops with kdtrace's message. If the driver itself dies, run the same command again
with --parts-dir DIR --resume: the parts already in DIR are kept, the others rendered.

Test hook (documented, used by tests/farm.rs only): KDTRACE_FARM_TEST_DELAY_S=SEC in the
driver's environment makes every task wait SEC seconds after reporting its start and before
running kdtrace, so that a test can kill a node while a range is certainly in flight.
"""
import argparse
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from ranges import sample_ranges  # noqa: E402  (farm/ranges.py, beside this file)

DEFAULT_KDTRACE = os.path.join(os.path.dirname(HERE), "target", "release", "kdtrace")
# `kdtrace render` flags passed through unchanged, with the values given here.
RENDER_FLAGS = ["width", "height", "bounces", "eye", "target", "up", "fov", "seed", "device"]


def parse_args(argv):
    p = argparse.ArgumentParser(
        description="Render SCENE on a Ray cluster in K sample ranges and merge them into IMAGE.",
        epilog="Environment: KDTRACE_FARM_TEST_DELAY_S (test hook, see the module's docstring).",
    )
    p.add_argument("scene", metavar="SCENE", help="scene file (.obj, .toml, .gltf/.glb, .kdc)")
    p.add_argument("--spp", type=int, required=True, help="samples per pixel of the whole image")
    p.add_argument("--tasks", type=int, required=True, help="number of sample ranges (Ray tasks)")
    p.add_argument("--out", required=True, metavar="IMAGE", help="merged image, .exr or .png")
    p.add_argument("--variance", metavar="VAR.exr", help="also write per-pixel variance (kdtrace merge --variance)")
    p.add_argument("--address", help="Ray cluster address HOST:PORT (default: RAY_ADDRESS, else a local Ray)")
    p.add_argument("--width", type=int)
    p.add_argument("--height", type=int)
    p.add_argument("--bounces", type=int)
    p.add_argument("--eye", metavar="X,Y,Z")
    p.add_argument("--target", metavar="X,Y,Z")
    p.add_argument("--up", metavar="X,Y,Z")
    p.add_argument("--fov", type=float, metavar="DEG")
    p.add_argument("--seed", type=int)
    p.add_argument("--device", help="kdtrace render --device on the workers (cpu, gpu, all, ...; default cpu)")
    p.add_argument("--kdtrace", default=DEFAULT_KDTRACE, help="the kdtrace binary (default: %(default)s)")
    p.add_argument("--ship", action="store_true", help="send the binary and the scene file through Ray's object store")
    p.add_argument("--cpus-per-task", type=int, default=1, help="CPUs Ray reserves per task; kdtrace runs as many threads (default 1)")
    p.add_argument("--gpus-per-task", type=float, default=0, help="GPUs Ray reserves per task, for --device gpu (default 0)")
    p.add_argument("--max-retries", type=int, default=3, help="Ray re-runs of a range whose worker or node died (default 3)")
    p.add_argument("--parts-dir", help="keep the partial files here (default: a temporary folder, removed)")
    p.add_argument("--resume", action="store_true",
                   help="with --parts-dir: keep the parts already there from an earlier run of the same command, "
                        "render only the missing ones")
    p.add_argument("--json", action="store_true", help="print one JSON report on stdout at the end")
    p.add_argument("--verbose", action="store_true", help="show Ray's own log lines")
    a = p.parse_args(argv)
    try:
        a.ranges = sample_ranges(a.spp, a.tasks)
    except ValueError as e:
        p.error(str(e))
    if a.resume and not a.parts_dir:
        p.error("--resume needs --parts-dir, the folder of the earlier run's parts")
    if a.cpus_per_task < 1 or a.max_retries < 0:
        p.error("--cpus-per-task must be at least 1 and --max-retries at least 0")
    for what, path in [("scene", a.scene), ("kdtrace binary", a.kdtrace)]:
        if not os.path.isfile(path):
            p.error(f"the {what} {path} does not exist")
    a.scene = os.path.abspath(a.scene)
    a.kdtrace = os.path.abspath(a.kdtrace)
    return a


def render_args(a):
    """The flags every range's `kdtrace render` gets besides the scene, range and output."""
    out = []
    for name in RENDER_FLAGS:
        value = getattr(a, name)
        if value is not None:
            out += [f"--{name}", str(value)]
    return out


def log(msg):
    print(f"ray_render: {msg}", file=sys.stderr, flush=True)


def die_with_parent():
    """In the child before exec: kdtrace gets SIGKILL when the Ray worker that started it dies
    (Linux prctl PR_SET_PDEATHSIG), so a crashed worker leaves no render running."""
    if sys.platform.startswith("linux"):
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)


class RenderFailed(Exception):
    """kdtrace itself failed on a range: a deterministic error, not retried."""


# What runs on the cluster. Plain Python here; main() makes them a Ray actor and a Ray task
# (ray.remote), after checking that Ray is installed.


class Ledger:
    """Where the tasks report their starts, an actor on the driver's node: a second start of
    a range is Ray's retry of it."""

    def __init__(self):
        self.events = []
        self.nodes = {}

    def started(self, index, node_id, ip):
        self.nodes.setdefault(index, []).append((node_id, ip))
        attempt = len(self.nodes[index])
        self.events.append({"index": index, "node_id": node_id, "ip": ip, "attempt": attempt,
                            "previous": self.nodes[index][-2] if attempt > 1 else None})
        return attempt

    def since(self, k):
        return self.events[k:]


def materialize(job, ip):
    """The paths of the binary and the scene on this node: the shared paths, or with --ship
    the copies in this node's cache (written from Ray's object store the first time)."""
    import ray

    if not job["ship"]:
        for what, path in [("kdtrace binary", job["kdtrace"]), ("scene", job["scene"])]:
            if not os.path.isfile(path):
                raise RenderFailed(f"the {what} {path} does not exist on node {ip} "
                                   "(without --ship, it must be at the same path on every node)")
        return job["kdtrace"], job["scene"]
    cache = os.path.join(tempfile.gettempdir(), "kdtrace-farm-cache", job["ship_key"])
    paths = os.path.join(cache, "kdtrace"), os.path.join(cache, job["scene_name"])
    if not all(os.path.isfile(p) for p in paths):
        os.makedirs(cache, exist_ok=True)
        for path, ref, mode in zip(paths, job["ship_refs"], (0o755, 0o644)):
            tmp = f"{path}.{os.getpid()}.tmp"
            with open(tmp, "wb") as f:
                f.write(ray.get(ref))
            os.chmod(tmp, mode)
            os.replace(tmp, path)  # atomic: a task beside this one sees all or nothing
    return paths


def render_range(index, start, end, job, ledger):
    """One range on a worker: report the start, run `kdtrace render --partial`, return the
    part's bytes."""
    import ray

    node_id = ray.get_runtime_context().get_node_id()
    ip = ray.util.get_node_ip_address()
    attempt = ray.get(ledger.started.remote(index, node_id, ip))
    if job["test_delay_s"] > 0:
        time.sleep(job["test_delay_s"])  # the documented test hook
    kdtrace, scene = materialize(job, ip)
    t0 = time.time()
    with tempfile.TemporaryDirectory(prefix="kdtrace-farm-") as d:
        part = os.path.join(d, f"part-{index:05d}.kdp")
        cmd = [kdtrace, "render", scene, "--samples", f"{start}..{end}", "--partial", part, *job["args"]]
        env = dict(os.environ, RAYON_NUM_THREADS=str(job["threads"]))
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env, preexec_fn=die_with_parent)
        if proc.returncode < 0:
            # Killed by a signal (the OOM killer, a node's shutdown): not kdtrace's verdict on the
            # range, so Ray runs it again (retry_exceptions; a built-in type, so that Ray's check
            # on the worker matches it).
            raise InterruptedError(f"kdtrace on {ip} was killed by signal {-proc.returncode}")
        if proc.returncode != 0:
            raise RenderFailed(f"`{' '.join(cmd)}` on {ip} exited with {proc.returncode}:\n{proc.stderr.strip()}")
        with open(part, "rb") as f:
            data = f.read()
    return {"index": index, "node_id": node_id, "ip": ip, "attempt": attempt,
            "render_s": time.time() - t0, "data": data}


# The driver.


def ship(a, ray):
    """--ship: the binary and the scene into Ray's object store, once."""
    if not a.scene.endswith(".kdc"):
        log(f"warning: --ship sends {a.scene} alone; files it names do not travel (compile it to a .kdc)")
    blobs = []
    for path in (a.kdtrace, a.scene):
        with open(path, "rb") as f:
            blobs.append(f.read())
    key = hashlib.sha256()
    for b in blobs:
        key.update(hashlib.sha256(b).digest())
    return {"ship_key": key.hexdigest()[:32], "scene_name": os.path.basename(a.scene),
            "ship_refs": [ray.put(b) for b in blobs]}


class Progress:
    """The report: one entry per range, and a line on stderr per start, retry and finish."""

    def __init__(self, ranges):
        self.ranges = [{"index": i, "samples": f"{s}..{e}", "attempts": 0, "nodes": []}
                       for i, (s, e) in enumerate(ranges)]
        self.seen = 0
        self.done = 0

    def started(self, events):
        """The ledger's new start events."""
        for ev in events:
            self.seen += 1
            r = self.ranges[ev["index"]]
            r["attempts"] = ev["attempt"]
            r["nodes"].append(ev["ip"])
            where = f"{ev['ip']} (node {ev['node_id'][:8]})"
            if ev["attempt"] == 1:
                log(f"range {r['samples']} started on {where}")
            else:
                other = "another node" if ev["previous"][0] != ev["node_id"] else "the same node"
                log(f"range {r['samples']} retried on {other} (attempt {ev['attempt']}): {where}, "
                    f"after its run on {ev['previous'][1]} was lost")

    def finished(self, res):
        self.done += 1
        r = self.ranges[res["index"]]
        r.update(node=res["ip"], render_s=round(res["render_s"], 3), bytes=len(res["data"]))
        log(f"range {r['samples']} done on {res['ip']} in {res['render_s']:.2f} s "
            f"(attempt {res['attempt']}; {self.done}/{len(self.ranges)} ranges done)")

    def retries(self):
        return sum(max(r["attempts"] - 1, 0) for r in self.ranges)


def run_ranges(a, ray, parts_dir):
    """Every range as a Ray task; each part written into parts_dir as it arrives. Returns the
    progress report and the parts' paths in range order."""
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

    job = {"kdtrace": a.kdtrace, "scene": a.scene, "args": render_args(a), "ship": a.ship,
           "threads": a.cpus_per_task, "test_delay_s": float(os.environ.get("KDTRACE_FARM_TEST_DELAY_S", "0"))}
    if a.ship:
        job.update(ship(a, ray))
    # The ledger lives on the driver's own node (hard affinity: a soft one lets Ray place it on
    # a worker, whose death would take the ledger with it).
    here = ray.get_runtime_context().get_node_id()
    ledger = ray.remote(num_cpus=0)(Ledger).options(
        scheduling_strategy=NodeAffinitySchedulingStrategy(here, soft=False)).remote()
    task = ray.remote(render_range).options(num_cpus=a.cpus_per_task, num_gpus=a.gpus_per_task,
                                            max_retries=a.max_retries, retry_exceptions=[InterruptedError])
    progress = Progress(a.ranges)
    paths = [os.path.join(parts_dir, f"part-{i:05d}.kdp") for i in range(a.tasks)]
    todo = list(range(a.tasks))
    if a.resume:
        # A part is only ever there complete (written under another name, then renamed); one
        # from a different render or split is refused by the merge, naming it.
        todo = [i for i in todo if not os.path.isfile(paths[i])]
        for i in sorted(set(range(a.tasks)) - set(todo)):
            progress.ranges[i]["kept"] = True
            progress.done += 1
            log(f"range {progress.ranges[i]['samples']}: part kept from {paths[i]}")
    pending = {task.remote(i, *a.ranges[i], job, ledger): i for i in todo}
    while pending:
        ready, _ = ray.wait(list(pending), num_returns=1, timeout=0.5)
        progress.started(ray.get(ledger.since.remote(progress.seen)))
        for ref in ready:
            samples = progress.ranges[pending.pop(ref)]["samples"]
            try:
                res = ray.get(ref)
            except ray.exceptions.RayTaskError as e:
                sys.exit(f"ray_render: range {samples} failed: {e.as_instanceof_cause()}")
            except ray.exceptions.RayError as e:
                sys.exit(f"ray_render: range {samples} was lost after {a.max_retries} retries: "
                         f"{type(e).__name__}: {e}")
            tmp = paths[res["index"]] + ".incomplete"
            with open(tmp, "wb") as f:
                f.write(res["data"])
            os.replace(tmp, paths[res["index"]])
            progress.finished(res)
    progress.started(ray.get(ledger.since.remote(progress.seen)))
    return progress, paths


def main(argv=None):
    a = parse_args(argv)
    try:
        import ray
    except ImportError:
        sys.exit("ray_render: Ray is not installed here: run farm/setup.sh and use farm/.venv/bin/python")
    import logging

    t_start = time.time()
    ray.init(address=a.address, log_to_driver=a.verbose, logging_level=logging.INFO if a.verbose else logging.WARNING)
    connect_s = time.time() - t_start
    nodes = [n for n in ray.nodes() if n["Alive"]]
    cpus = sum(n["Resources"].get("CPU", 0) for n in nodes)
    log(f"cluster: {len(nodes)} nodes, {cpus:g} CPUs; {a.tasks} ranges of {a.spp} samples, {a.cpus_per_task} CPU(s) each")

    parts_dir = a.parts_dir or tempfile.mkdtemp(prefix="kdtrace-farm-parts-")
    os.makedirs(parts_dir, exist_ok=True)
    try:
        try:
            progress, paths = run_ranges(a, ray, parts_dir)
        finally:
            ray.shutdown()
        render_wall = time.time() - t_start
        t_merge = time.time()
        cmd = [a.kdtrace, "merge", *paths, "--out", a.out] + (["--variance", a.variance] if a.variance else [])
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            sys.exit(f"ray_render: `{' '.join(cmd)}` exited with {proc.returncode}:\n{proc.stderr.strip()}")
        merge_s = time.time() - t_merge
        part_bytes = sum(os.path.getsize(p) for p in paths)
    finally:
        if not a.parts_dir:
            shutil.rmtree(parts_dir, ignore_errors=True)
    log(f"merged {a.tasks} ranges into {a.out} in {merge_s:.2f} s; {progress.retries()} retried; "
        f"{render_wall + merge_s:.1f} s in all")
    if a.json:
        print(json.dumps({
            "scene": a.scene, "out": a.out, "spp": a.spp, "tasks": a.tasks, "nodes": len(nodes),
            "retries": progress.retries(), "connect_s": round(connect_s, 3), "render_wall_s": round(render_wall, 3),
            "merge_s": round(merge_s, 3), "part_bytes": part_bytes, "ranges": progress.ranges,
        }))


if __name__ == "__main__":
    main()
