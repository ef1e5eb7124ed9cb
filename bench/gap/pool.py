"""The campaigns' process pool: runs mapped over forked worker processes,
in order, with a progress line (count, time elapsed, time left) on stderr."""
from __future__ import annotations

import multiprocessing as mp
import sys
import time


def pool_map(fn, items, workers: int, progress: bool, label: str):
    """map over items with a process pool (fork) and a progress line; keeps order."""
    items = list(items)
    out = [None] * len(items)
    t0 = time.time()

    def show(done):
        if progress:
            el = time.time() - t0
            eta = el / done * (len(items) - done) if done else 0.0
            print(f"\r  {label}: {done}/{len(items)} runs, {el:6.0f} s elapsed, ~{eta:5.0f} s left",
                  end="", flush=True, file=sys.stderr)

    if workers <= 1 or len(items) <= 1:
        for i, it in enumerate(items):
            out[i] = fn(it)
            show(i + 1)
    else:
        ctx = mp.get_context("fork")
        with ctx.Pool(workers) as pool:
            for done, (i, r) in enumerate(pool.imap_unordered(_indexed, [(fn, i, it) for i, it in enumerate(items)]), 1):
                out[i] = r
                show(done)
    if progress:
        print(file=sys.stderr)
    return out


def _indexed(arg):
    fn, i, it = arg
    return i, fn(it)
