"""Timing of the thruster learner's step: C++ (Google Benchmark, bench_blr)
beside the numpy implementation (bench/perf/blr_numpy.py) and the bindings, in
one run. 9 inputs (8 valves + bias), 6 outputs, window 30, double.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python -m bench.perf.perf_blr [--bench-exe PATH] [--json OUT]
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import platform
import subprocess
import sys
import time
import timeit
from pathlib import Path

import numpy as np

from bench.perf.blr_numpy import NumpyBlr
from bench.report import write_json

REPS = 9
ROOT = Path(__file__).resolve().parents[2]


def find_exe(path=None):
    if path:
        return path
    cands = glob.glob(str(ROOT / "build" / "*" / "bench_blr"))
    return max(cands, key=os.path.getmtime) if cands else None


def run_cpp(exe):
    cmd = [exe, f"--benchmark_repetitions={REPS}", "--benchmark_report_aggregates_only=true", "--benchmark_format=json"]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    res = {}
    for b in json.loads(out)["benchmarks"]:
        if b.get("aggregate_name") == "median":
            assert b["time_unit"] == "ns"
            res[b["run_name"]] = {"real": b["real_time"], "cpu": b["cpu_time"]}
    return " ".join(cmd), res


def data(n=1024, seed=11):
    rng = np.random.default_rng(seed)
    mask, xs, ys = 0, [], []
    for _ in range(n):
        mask ^= 1 << int(rng.integers(8))
        xs.append(np.r_[[(mask >> i) & 1 for i in range(8)], 1.0].astype(float))
        ys.append(1e-3 * rng.standard_normal(6))
    return xs, ys, mask


def median_ns(fn, number):
    """Median over REPS repetitions of wall-clock and process CPU time per call [ns]."""
    out = {}
    for name, timer in (("real", time.perf_counter), ("cpu", time.process_time)):
        out[name] = float(np.median(timeit.repeat(fn, number=number, repeat=REPS, timer=timer)) / number * 1e9)
    return out


def time_numpy():
    xs, ys, _ = data()
    b = NumpyBlr()
    for i in range(30):
        b.add(xs[i], ys[i])
    it = iter(range(10**9))

    def add_remove():
        i = next(it) & 1023
        b.add(xs[i], ys[i])

    def add_then_predict():
        i = next(it) & 1023
        b.add(xs[i], ys[i])
        b.predict(xs[(i + 7) & 1023])

    ar = median_ns(add_remove, 2000)
    ap = median_ns(add_then_predict, 2000)
    return {"AddRemove": ar, "AddThenPredict": ap}


def time_bindings():
    try:
        import fsw_bindings as fb
    except ImportError:
        return {}
    xs, ys, _ = data()
    b = fb.ThrusterBlr()
    for i in range(30):
        b.add(xs[i], ys[i])
    it = iter(range(10**9))

    def add_remove():
        i = next(it) & 1023
        b.add(xs[i], ys[i])

    def add_then_predict():
        i = next(it) & 1023
        b.add(xs[i], ys[i])
        b.predict(xs[(i + 7) & 1023])

    ar = median_ns(add_remove, 5000)
    ap = median_ns(add_then_predict, 5000)
    return {"AddRemove": ar, "AddThenPredict": ap}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--bench-exe", default=None, help="bench_blr executable (default: newest build/*/bench_blr)")
    p.add_argument("--json", default=None)
    a = p.parse_args(argv)
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    cpu = subprocess.run("lscpu | grep 'Model name'", shell=True, capture_output=True, text=True).stdout.strip()
    out = {
        "cpu": cpu,
        "nproc": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "command": " ".join([sys.executable, "-m", "bench.perf.perf_blr"] + (argv or sys.argv[1:])),
    }
    exe = find_exe(a.bench_exe)
    if exe:
        out["cpp_command"], out["cpp_median_ns"] = run_cpp(exe)
    out["numpy_median_ns"] = time_numpy()
    out["bindings_median_ns"] = time_bindings()
    out["loadavg_1min"] = os.getloadavg()[0]
    # Prediction after a window change, derived: (add then predict) - (add).
    for key, num, den in (
        ("cpp_median_ns", "BM_PredictThenAdd<double>", "BM_AddRemove<double>"),
        ("numpy_median_ns", "AddThenPredict", "AddRemove"),
        ("bindings_median_ns", "AddThenPredict", "AddRemove"),
    ):
        d = out.get(key, {})
        if num in d and den in d:
            d["Predict after change (derived)"] = {t: d[num][t] - d[den][t] for t in ("real", "cpu")}
    print(f"{cpu}; nproc {out['nproc']}; 1-min load average {out['loadavg_1min']:.1f}")
    print(f"{'':40s} {'wall [ns]':>12s} {'cpu [ns]':>12s}")
    for key, title in (
        ("cpp_median_ns", f"C++ ({out.get('cpp_command', 'not found')})"),
        (
            "numpy_median_ns",
            "numpy (bench/perf/blr_numpy.py), OPENBLAS_NUM_THREADS=" + os.environ["OPENBLAS_NUM_THREADS"],
        ),
        ("bindings_median_ns", "bindings (fsw_bindings.ThrusterBlr, Python call included)"),
    ):
        print(title + ":")
        for k, v in out.get(key, {}).items():
            print(f"  {k:38s} {v['real']:12.1f} {v['cpu']:12.1f}")
    if a.json:
        write_json(a.json, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
