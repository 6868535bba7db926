#!/usr/bin/env python3
"""Which samples each task of a farm render draws: the one place that maps a task index to a
sample range, used by all three drivers (farm/ray_render.py imports it; the Slurm array and the
Kubernetes Indexed Job call it through farm/render_range.sh).

`kdtrace render --samples A..B --partial` needs A to be a multiple of the block size (8) and B a
multiple of 8 or the end of the render, so the render's samples are cut into blocks of 8 and
task i of K gets blocks [floor(i*n/K), floor((i+1)*n/K)) of the n = ceil(spp/8) blocks, the last
block cut at spp. Every task gets at least one block, so K may be at most n.

    python3 farm/ranges.py --spp 64 --tasks 8 --index 2     # prints 16..24
    python3 farm/ranges.py --spp 64 --tasks 8               # prints all 8 ranges, one a line

Python 3 standard library only: it runs on any node that has python3.
"""
import argparse
import sys

BLOCK = 8  # kdtrace's sample block: partial renders start on multiples of it


def sample_ranges(spp, tasks, block=BLOCK):
    """The K half-open sample ranges (start, end) of a render of `spp` samples, in task order."""
    if spp < 1:
        raise ValueError(f"spp must be at least 1, not {spp}")
    blocks = -(-spp // block)
    if not 1 <= tasks <= blocks:
        raise ValueError(
            f"{tasks} tasks for {spp} samples: each task needs at least one block of {block} "
            f"samples, so there can be 1 to {blocks} tasks"
        )
    out = []
    for i in range(tasks):
        first, last = i * blocks // tasks, (i + 1) * blocks // tasks
        out.append((first * block, min(last * block, spp)))
    return out


def sample_range(spp, tasks, index, block=BLOCK):
    """Task `index`'s range (0 ≤ index < tasks)."""
    if not 0 <= index < tasks:
        raise ValueError(f"task index {index} is outside 0..{tasks - 1}")
    return sample_ranges(spp, tasks, block)[index]


def main(argv=None):
    p = argparse.ArgumentParser(description="Sample range(s) of a farm render's task(s), as A..B")
    p.add_argument("--spp", type=int, required=True, help="samples per pixel of the whole render")
    p.add_argument("--tasks", type=int, required=True, help="number of tasks K")
    p.add_argument("--index", type=int, help="one task's index, 0..K-1 (default: print all K)")
    a = p.parse_args(argv)
    try:
        if a.index is None:
            for start, end in sample_ranges(a.spp, a.tasks):
                print(f"{start}..{end}")
        else:
            start, end = sample_range(a.spp, a.tasks, a.index)
            print(f"{start}..{end}")
    except ValueError as e:
        print(f"ranges.py: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
