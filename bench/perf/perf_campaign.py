"""What running a campaign through Dask costs: per-run overhead beside a
multiprocessing fork pool, and the speed-up from one to two local workers.

    python -m bench.perf.perf_campaign --json OUT

Overhead: a run that does nothing (returns its index), mapped over
--noop-runs runs, --repeats times, median wall time per run: through the
fork pool (multiprocessing.Pool.imap_unordered, the pool campaigns ran on
before; started per campaign) and through bench.runner (a warm local
Dask cluster, each record written to a results store on disk, or kept in
memory). Speed-up: a
null calibration of --null-runs real runs (bench/gap/null.py, 120 s
docking logs) on a fresh local cluster of 1 and of 2 workers (cluster start
included), and through the fork pool with 2 processes.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import platform
import statistics
import sys
import tempfile
import time


def _noop(i):
    return {"run": i}


def _fork_pool_map(fn, items, workers):
    out = [None] * len(items)
    with mp.get_context("fork").Pool(workers) as pool:
        for i, r in pool.imap_unordered(_indexed, [(fn, i, it) for i, it in enumerate(items)]):
            out[i] = r
    return out


def _indexed(arg):
    fn, i, it = arg
    return i, fn(it)


def _null_run(seed):
    from bench.campaigns.gap.null_calibration import run_statistics

    return run_statistics(int(seed), (120.0, "docking"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--noop-runs", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--null-runs", type=int, default=24)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    from bench.runner import cluster
    from bench.runner.runner import Campaign
    from bench.runner.store import RunStore

    res = {
        "machine": {
            "cpus": os.cpu_count(),
            "processor": platform.processor() or platform.machine(),
            "python": platform.python_version(),
        },
        "noop_runs": a.noop_runs,
        "repeats": a.repeats,
    }
    items = list(range(a.noop_runs))
    pool_t, dask_t, mem_t = [], [], []
    t0 = time.perf_counter()
    cluster.client(workers=2)
    res["local_cluster_start_s"] = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(a.repeats):
            t0 = time.perf_counter()
            _fork_pool_map(_noop, items, 2)
            pool_t.append((time.perf_counter() - t0) / len(items))
            t0 = time.perf_counter()
            Campaign(
                RunStore("noop", {"repeat": r}, root=tmp), workers=2, progress=False, stream=open(os.devnull, "w")
            ).map("noop", _noop, items)
            dask_t.append((time.perf_counter() - t0) / len(items))
            t0 = time.perf_counter()
            Campaign(None, workers=2, progress=False).map("noop", _noop, items)
            mem_t.append((time.perf_counter() - t0) / len(items))
    res["per_run_overhead_ms"] = {
        "fork_pool_2": 1e3 * statistics.median(pool_t),
        "dask_local_2_with_store": 1e3 * statistics.median(dask_t),
        "dask_local_2_no_store": 1e3 * statistics.median(mem_t),
    }
    cluster.close_all()
    seeds = [7000 + i for i in range(a.null_runs)]
    walls = {}
    for n in (1, 2):
        t0 = time.perf_counter()
        recs = Campaign(None, workers=n, progress=False).map("null", _null_run, seeds)
        walls[f"dask_local_{n}"] = time.perf_counter() - t0
        cluster.close_all()
        res.setdefault("null_results_identical", []).append([r["result"] for r in recs])
    t0 = time.perf_counter()
    pool = _fork_pool_map(_null_run, seeds, 2)
    walls["fork_pool_2"] = time.perf_counter() - t0
    same = res.pop("null_results_identical")
    res["null_results_identical"] = same[0] == same[1] == pool
    res["null_calibration_wall_s"] = walls
    res["speedup_1_to_2_workers"] = walls["dask_local_1"] / walls["dask_local_2"]
    res["null_runs"] = a.null_runs
    text = json.dumps(res, indent=1)
    print(text)
    if a.json:
        with open(a.json, "w") as f:
            f.write(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
