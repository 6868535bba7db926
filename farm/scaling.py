#!/usr/bin/env python3
"""A model of a farm render's time on N nodes, from figures measured on one machine
(bench/farm_scaling.sh writes them): where the speed-up comes from, and where start-up or the
merge eat it.

One render of SPP samples is cut into K ranges (farm/ranges.py: whole blocks of 8; K = N unless
--tasks says otherwise), spread over N nodes that each run ceil(K / N) of them one after another,
every task paying its start-up. The image is ready when the slowest node is done and every part
has reached the merging machine and been merged:

    T(N)  = ceil(K / N) · (start + ceil(B / K) · 8 · t_sample) + merge(K)   B = ceil(SPP / 8) blocks
    T(1)  = start + SPP · t_sample                    (one machine, one task: no part, no merge)

With --cores C (a local check: N one-CPU "nodes" sharing C cores) at most C nodes compute at
once, so N counts as min(N, C).

  start           per task, paid once on every node in parallel: process start, scene parse and
                  k-d build (or .kdc load), GPU kernel compile, plus the scheduler's dispatch
  t_sample        seconds per sample per pixel of the whole image on one node
  merge(N), flat  N · part_bytes · (1 / bandwidth + merge_s_per_byte): every part crosses the
                  merging machine's link and is added there, one after another
  merge(N), tree  ceil(log2 N) · part_bytes · (1 / bandwidth + merge_s_per_byte): parts merged
                  pairwise on the nodes, log N rounds (a possible change, not what the drivers do)

Start-up dominates once a range's compute, SPP · t_sample / N, falls below `start`, i.e. past
N_start = SPP · t_sample / start. The flat merge dominates past N_merge, where N · c equals
SPP · t_sample / N (c the per-part merge cost), i.e. N_merge = sqrt(SPP · t_sample / c), which
is also about where T(N) is smallest. N beyond B gives nothing more: a range is one block.

    python3 farm/scaling.py --measured bench/results/farm_scaling-*.json [--spp 4096 --bandwidth-gbit 10]
    python3 farm/scaling.py --t-sample 0.5 --start 2.0 --part-mb 96 --spp 4096
"""
import argparse
import json
import math
import sys


def model(spp, t_sample, start, part_bytes, bandwidth, merge_s_per_byte, n, tree=False, tasks=None, cores=None):
    """Predicted seconds for one render on n nodes in `tasks` ranges (default n), at most
    `cores` of the nodes computing at once (default all)."""
    blocks = math.ceil(spp / 8)
    k = min(tasks or n, blocks)  # more ranges than blocks is impossible
    nodes = min(n, k, cores or n)
    if k == 1:
        return start + spp * t_sample
    rounds = math.ceil(k / nodes)
    compute = math.ceil(blocks / k) * 8 * t_sample
    per_part = part_bytes * (1 / bandwidth + merge_s_per_byte)
    merge = (math.ceil(math.log2(k)) if tree else k) * per_part
    return rounds * (start + compute) + merge


def main(argv=None):
    p = argparse.ArgumentParser(description="Predicted speed-up of a farm render for 1 to 1,000 nodes")
    p.add_argument("--measured", help="JSON written by bench/farm_scaling.sh (its figures are the defaults below)")
    p.add_argument("--spp", type=int, help="samples per pixel of the render to predict")
    p.add_argument("--t-sample", type=float, help="seconds per sample per pixel of the image, one node")
    p.add_argument("--start", type=float, help="seconds of start-up per task (process, scene, kernel, dispatch)")
    p.add_argument("--part-mb", type=float, help="size of one partial file, MB")
    p.add_argument("--bandwidth-gbit", type=float, default=10.0, help="the merging machine's link, Gbit/s (default 10)")
    p.add_argument("--merge-mb-per-s", type=float, help="merge speed, MB of parts added per second")
    p.add_argument("--json", action="store_true", help="print the table as JSON")
    a = p.parse_args(argv)

    m = {}
    if a.measured:
        try:
            with open(a.measured) as f:
                m = json.load(f)["model_inputs"]
        except (OSError, KeyError, ValueError) as e:
            sys.exit(f"scaling.py: cannot read model inputs from {a.measured}: {e}")
    spp = a.spp or m.get("spp")
    t_sample = a.t_sample if a.t_sample is not None else m.get("t_sample_s")
    start = a.start if a.start is not None else m.get("start_s")
    part_bytes = a.part_mb * 1e6 if a.part_mb is not None else m.get("part_bytes")
    merge_rate = a.merge_mb_per_s * 1e6 if a.merge_mb_per_s is not None else m.get("merge_bytes_per_s")
    missing = [n for n, v in [("--spp", spp), ("--t-sample", t_sample), ("--start", start), ("--part-mb", part_bytes),
                              ("--merge-mb-per-s", merge_rate)] if v is None]
    if missing:
        p.error(f"give --measured or {', '.join(missing)}")
    bandwidth = a.bandwidth_gbit * 1e9 / 8
    per_byte = 1 / merge_rate

    nodes = [1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1000]
    t1 = model(spp, t_sample, start, part_bytes, bandwidth, per_byte, 1)
    rows = []
    for n in nodes:
        flat = model(spp, t_sample, start, part_bytes, bandwidth, per_byte, n)
        tree = model(spp, t_sample, start, part_bytes, bandwidth, per_byte, n, tree=True)
        compute = math.ceil(math.ceil(spp / 8) / min(n, math.ceil(spp / 8))) * 8 * t_sample
        merge = flat - start - compute if n > 1 else 0.0
        dominant = max([("compute", compute), ("start-up", start), ("merge", merge)], key=lambda x: x[1])[0]
        rows.append({"nodes": n, "seconds": flat, "speedup": t1 / flat, "efficiency": t1 / flat / n,
                     "seconds_tree_merge": tree, "speedup_tree_merge": t1 / tree, "dominant": dominant})
    per_part = part_bytes * (1 / bandwidth + per_byte)
    n_start = spp * t_sample / start if start > 0 else math.inf
    n_merge = math.sqrt(spp * t_sample / per_part) if per_part > 0 else math.inf
    inputs = {"spp": spp, "t_sample_s": t_sample, "start_s": start, "part_bytes": part_bytes,
              "bandwidth_bytes_per_s": bandwidth, "merge_bytes_per_s": merge_rate}
    if a.json:
        print(json.dumps({"inputs": inputs, "n_start": n_start, "n_merge": n_merge, "rows": rows}))
        return
    print(f"inputs: {spp} spp, {t_sample:.4g} s per sample per image on one node ({spp * t_sample:.4g} s of "
          f"compute), start-up {start:.3g} s per task, parts {part_bytes / 1e6:.3g} MB, link "
          f"{a.bandwidth_gbit:g} Gbit/s, merge {merge_rate / 1e6:.3g} MB/s")
    print(f"{'nodes':>6} {'time s':>10} {'speed-up':>9} {'effic.':>7} {'dominant':>9} {'tree-merge s':>13} {'speed-up':>9}")
    for r in rows:
        print(f"{r['nodes']:>6} {r['seconds']:>10.4g} {r['speedup']:>9.3g} {r['efficiency']:>7.2f} {r['dominant']:>9} "
              f"{r['seconds_tree_merge']:>13.4g} {r['speedup_tree_merge']:>9.3g}")
    print(f"start-up outweighs a range's compute past N_start = {n_start:.3g} nodes; the flat merge outweighs it "
          f"past N_merge = {n_merge:.3g} nodes (about the fastest N); {math.ceil(spp / 8)} blocks cap N")


if __name__ == "__main__":
    main()
