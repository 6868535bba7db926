#!/usr/bin/env python3
"""Local tests of the farm recipes, run by tests/farm.rs (`cargo test --test farm`):

  ranges  farm/ranges.py: for many (spp, K), the K ranges are contiguous, cover 0..spp, start
          on multiples of 8 and end on one or at spp; bad K is refused.
  slurm   runs farm/slurm/render.sbatch once per array index (SLURM_ARRAY_TASK_ID=i, as Slurm
          would), then farm/slurm/merge.sbatch, and compares the merged EXR with one
          `kdtrace render` of the same settings, byte for byte; then farm/slurm/submit.sh
          against a stand-in sbatch that runs the jobs at once (the array's sbatch options and
          the merge's afterok dependency checked), and compares again.
  k8s     validates farm/k8s/*.yaml against the Kubernetes API schemas (kubernetes-validate,
          --strict), checks the Indexed Job's completions equal its TASKS, runs the render
          container's command once per index (JOB_COMPLETION_INDEX=i) and the merge Job's
          command, with the container's paths mapped to local ones, and compares as above.

    python3 farm/test_recipes.py {ranges,slurm,k8s} --kdtrace BIN --scene SCENE --work DIR

The `k8s` test needs PyYAML and kubernetes-validate (farm/setup.sh --tests); the others only
the standard library.
"""
import argparse
import os
import shutil
import subprocess
import sys

FARM = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, FARM)
from ranges import sample_ranges  # noqa: E402

# The test render: small enough for a test, several ranges of several blocks.
SPP, TASKS = 64, 8
RENDER_ARGS = ["--width", "32", "--height", "32", "--bounces", "1", "--seed", "3"]


def run(cmd, env=None, what=None):
    p = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"FAIL: {what or ' '.join(cmd)} exited with {p.returncode}:\n{p.stdout}{p.stderr}")
    return p


def reference(a, out):
    """One `kdtrace render` of the test settings: what every recipe's merge must equal."""
    run([a.kdtrace, "render", a.scene, "--spp", str(SPP), *RENDER_ARGS, "--out", out])


def same_bytes(got, want, recipe):
    with open(got, "rb") as f, open(want, "rb") as g:
        if f.read() != g.read():
            sys.exit(f"FAIL: {recipe}: the merged {got} differs from the single render {want}")
    print(f"{recipe}: merged image equals `kdtrace render` byte for byte ({want})")


def test_ranges(a):
    for spp in list(range(1, 130)) + [1000, 4096, 65537]:
        blocks = -(-spp // 8)
        for k in sorted({1, 2, 3, 7, 8, blocks // 2, blocks} & set(range(1, blocks + 1))):
            r = sample_ranges(spp, k)
            assert len(r) == k and r[0][0] == 0 and r[-1][1] == spp, (spp, k, r)
            assert all(r[i][1] == r[i + 1][0] for i in range(k - 1)), (spp, k, r)
            assert all(s % 8 == 0 and s < e and (e % 8 == 0 or e == spp) for s, e in r), (spp, k, r)
        for bad in (0, blocks + 1):
            try:
                sample_ranges(spp, bad)
                sys.exit(f"FAIL: {bad} tasks for {spp} spp were accepted")
            except ValueError:
                pass
    # The command line that the shell recipes call.
    out = run([sys.executable, os.path.join(FARM, "ranges.py"), "--spp", "64", "--tasks", "8", "--index", "2"])
    assert out.stdout.strip() == "16..24", out.stdout
    print("ranges: contiguous, block-aligned, covering; bad task counts refused")


def test_slurm(a):
    work = os.path.join(a.work, "slurm")
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    want = os.path.join(work, "single.exr")
    reference(a, want)
    env = dict(os.environ, FARM_DIR=FARM, KDTRACE=a.kdtrace, SCENE=a.scene, SPP=str(SPP), TASKS=str(TASKS),
               PARTS_DIR=os.path.join(work, "parts"), OUT=os.path.join(work, "merged.exr"),
               RENDER_ARGS=" ".join(RENDER_ARGS), SLURM_SUBMIT_DIR=os.path.dirname(FARM))
    # As `sbatch --array=0-7` would: the script's body once per index (in reverse order: the
    # order tasks finish in must not matter).
    for i in reversed(range(TASKS)):
        run(["bash", os.path.join(FARM, "slurm", "render.sbatch")], dict(env, SLURM_ARRAY_TASK_ID=str(i)),
            f"render.sbatch with SLURM_ARRAY_TASK_ID={i}")
    parts = sorted(os.listdir(env["PARTS_DIR"]))
    assert parts == [f"part-{i:05d}.kdp" for i in range(TASKS)], parts
    run(["bash", os.path.join(FARM, "slurm", "merge.sbatch")], env, "merge.sbatch")
    same_bytes(env["OUT"], want, "slurm")
    # The merge step names what is missing.
    os.remove(os.path.join(env["PARTS_DIR"], "part-00005.kdp"))
    p = subprocess.run(["bash", os.path.join(FARM, "slurm", "merge.sbatch")], env=env, capture_output=True, text=True)
    assert p.returncode != 0 and "task indexes 5" in p.stderr, p.stderr
    # A task outside the array is refused by ranges.py.
    p = subprocess.run(["bash", os.path.join(FARM, "slurm", "render.sbatch")], env=dict(env, SLURM_ARRAY_TASK_ID="8"),
                       capture_output=True, text=True)
    assert p.returncode != 0 and "outside 0..7" in p.stderr, p.stderr
    print("slurm: a missing part and an index outside the array are refused with their numbers")

    # farm/slurm/submit.sh against a stand-in sbatch that runs each job at once, the array once
    # per index, and records its command lines.
    bin_dir = os.path.join(work, "bin")
    os.makedirs(bin_dir)
    with open(os.path.join(bin_dir, "sbatch"), "w") as f:
        f.write(FAKE_SBATCH)
    os.chmod(os.path.join(bin_dir, "sbatch"), 0o755)
    out = os.path.join(work, "submitted.exr")
    env = dict(os.environ, PATH=bin_dir + os.pathsep + os.environ["PATH"], KDTRACE=a.kdtrace, FAKE_SLURM_DIR=work)
    p = run(["bash", os.path.join(FARM, "slurm", "submit.sh"), a.scene, str(SPP), str(TASKS), out,
             os.path.join(work, "submitted-parts"), *RENDER_ARGS, "--", "--partition=render"], env, "slurm/submit.sh")
    with open(os.path.join(work, "calls")) as f:
        calls = f.read().splitlines()
    assert len(calls) == 2, calls
    assert "--array=0-7" in calls[0] and "--partition=render" in calls[0] and calls[0].endswith("render.sbatch"), calls
    assert "--dependency=afterok:101" in calls[1] and calls[1].endswith("merge.sbatch"), calls
    assert "render array 101 (tasks 0-7), merge job 102" in p.stdout, p.stdout
    same_bytes(out, want, "slurm/submit.sh")


# A stand-in for Slurm's sbatch (the test machines have no Slurm): runs the job script at once,
# an array's once per index with SLURM_ARRAY_TASK_ID set, records its arguments in
# $FAKE_SLURM_DIR/calls and prints a job id (101, 102, ...) as `sbatch --parsable` does.
FAKE_SBATCH = r"""#!/usr/bin/env bash
set -euo pipefail
array="" script=""
for arg in "$@"; do
  case $arg in
    --array=*) array=${arg#--array=} ;;
    -*) ;;
    *) script=$arg ;;
  esac
done
id=$(( $(cat "$FAKE_SLURM_DIR/last-id" 2>/dev/null || echo 100) + 1 ))
echo "$id" >"$FAKE_SLURM_DIR/last-id"
echo "$*" >>"$FAKE_SLURM_DIR/calls"
if [ -n "$array" ]; then
  for ((i = ${array%-*}; i <= ${array#*-}; i++)); do SLURM_ARRAY_TASK_ID=$i bash "$script" >&2; done
else
  bash "$script" >&2
fi
echo "$id"
"""


def container(doc):
    """The Job's one container, and its environment as a dict."""
    spec = doc["spec"]["template"]["spec"]
    assert len(spec["containers"]) == 1, "one container per pod"
    c = spec["containers"][0]
    return c, {e["name"]: e["value"] for e in c.get("env", [])}


def test_k8s(a):
    import yaml

    k8s = os.path.join(FARM, "k8s")
    files = sorted(os.path.join(k8s, f) for f in os.listdir(k8s) if f.endswith(".yaml"))
    validator = os.path.join(os.path.dirname(sys.executable), "kubernetes-validate")
    run([validator, "--strict", "--quiet", "-k", "1.29", *files], what="kubernetes-validate --strict")
    print(f"k8s: {len(files)} YAML files valid against the Kubernetes 1.29 API schemas")
    with open(os.path.join(k8s, "render-job.yaml")) as f:
        render = yaml.safe_load(f)
    with open(os.path.join(k8s, "merge-job.yaml")) as f:
        merge = yaml.safe_load(f)
    assert render["kind"] == "Job" and render["spec"]["completionMode"] == "Indexed"
    render_c, render_env = container(render)
    merge_c, merge_env = container(merge)
    completions = render["spec"]["completions"]
    assert int(render_env["TASKS"]) == completions == int(merge_env["TASKS"]), \
        f"completions {completions}, render TASKS {render_env['TASKS']}, merge TASKS {merge_env['TASKS']}"
    assert render_env["PARTS_DIR"] == merge_env["PARTS_DIR"]
    ranges = sample_ranges(int(render_env["SPP"]), completions)  # the Job's own SPP and K work
    print(f"k8s: {completions} completions = TASKS; the Job's {render_env['SPP']} spp cut as {ranges[0][0]}..{ranges[0][1]}, ...")

    work = os.path.join(a.work, "k8s")
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    want = os.path.join(work, "single.exr")
    reference(a, want)
    # The container's paths, mapped to this machine's; the test's small render in place of
    # the Job's.
    local = {"FARM_DIR": FARM, "KDTRACE": a.kdtrace, "SCENE": a.scene, "PARTS_DIR": os.path.join(work, "parts"),
             "OUT": os.path.join(work, "merged.exr"), "SPP": str(SPP), "TASKS": str(TASKS),
             "RENDER_ARGS": " ".join(RENDER_ARGS)}
    base = {"PATH": os.environ["PATH"], "HOME": os.environ.get("HOME", "/")}
    for i in range(TASKS):
        env = {**base, **render_env, **{k: v for k, v in local.items() if k in render_env}}
        run(render_c["command"], dict(env, JOB_COMPLETION_INDEX=str(i)), f"render container, JOB_COMPLETION_INDEX={i}")
    env = {**base, **merge_env, **{k: v for k, v in local.items() if k in merge_env}}
    run(merge_c["command"], env, "merge container")
    same_bytes(local["OUT"], want, "k8s")


def main():
    p = argparse.ArgumentParser(description="Local tests of the farm recipes")
    p.add_argument("test", choices=["ranges", "slurm", "k8s"])
    p.add_argument("--kdtrace", help="the kdtrace binary")
    p.add_argument("--scene", help="the test scene")
    p.add_argument("--work", help="a scratch folder")
    a = p.parse_args()
    if a.test != "ranges" and not (a.kdtrace and a.scene and a.work):
        p.error(f"the {a.test} test needs --kdtrace, --scene and --work")
    {"ranges": test_ranges, "slurm": test_slurm, "k8s": test_k8s}[a.test](a)
    print(f"{a.test}: ok")


if __name__ == "__main__":
    main()
