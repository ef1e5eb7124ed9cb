"""`proxops modal-timing`'s grid (its command line: bench/commands/modal.py):
the modal estimator's time per image in the grid of Table I of "Shape,
Motion, and Parameter Estimation of Large Flexible Space Structures using
Range Images" (Lichter and Dubowsky), the flight builds (Google Benchmark's
bench_modal, or the bindings) beside numpy (bench/perf/modal_numpy.py) and
the paper's figures."""

from __future__ import annotations

import json
import subprocess
import time

import numpy as np

from bench.perf import modal_numpy as mn

# The paper's Table I, seconds per sample on a 1 GHz Pentium III (None: not given).
PAPER_TABLE = {
    10: [0.030, 0.038, 0.18, 1.4],
    20: [0.22, 0.24, 0.65, 4.4],
    30: [0.87, 0.89, 1.7, 9.1],
    40: [2.1, 2.2, 3.5, None],
    50: [4.6, 4.8, 6.6, None],
}
GRID_N = [100, 1000, 10000, 100000]


def flight_bindings(m, n, kind, repeats):
    """Seconds per image through the bindings (decompose + step), M in MODAL_SIZES."""
    import fsw_bindings as fb

    rng = np.random.default_rng(1)
    x, y = rng.uniform(size=n), rng.uniform(size=n)
    p = 1 + np.arange(m) % 7
    q = 1 + np.arange(m) // 7
    phi = np.ascontiguousarray(np.sin(p * np.pi * x[:, None]) * np.sin(q * np.pi * y[:, None]))
    z = phi @ (0.1 * np.cos(np.arange(m))) + 0.01 * rng.standard_normal(n)
    from bench.campaigns.modal_campaign import make_filter

    w = 0.01 * (1 + np.arange(m))
    f = make_filter(kind, m, w, np.zeros(m), w, 0.1 * w, 1e-5, 1e-8, 1e-10)
    dec = getattr(fb, f"ModalDecomposition{m}")(sigma_e_m=0.01)
    f.step(60.0, dec.decompose(phi, z))
    times = []
    for _ in range(repeats):
        k, t0 = 0, time.perf_counter()
        while True:
            f.step(60.0, dec.decompose(phi, z))
            k += 1
            if time.perf_counter() - t0 >= 0.05:
                break
        times.append((time.perf_counter() - t0) / k)
    return float(np.median(times))


# Only the grid benchmarks (the per-point and frozen-base references are not part of Table I).
GRID_FILTER = "^BM_(Decomposition|Decoupled|Joint)<[0-9]+>/[0-9]+$"


def run_bench_exe(exe):
    out = subprocess.run(
        [
            exe,
            "--benchmark_repetitions=9",
            "--benchmark_report_aggregates_only=true",
            f"--benchmark_filter={GRID_FILTER}",
            "--benchmark_format=json",
        ],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    res = {}
    for b in json.loads(out)["benchmarks"]:
        if b.get("aggregate_name") != "median":
            continue
        name = b["run_name"]  # BM_Joint<10>/1000
        kind, rest = name.split("<", 1)
        m = int(rest.split(">")[0])
        n = int(name.split("/")[-1])
        scale = {"us": 1e-6, "ms": 1e-3, "ns": 1e-9, "s": 1.0}[b["time_unit"]]
        res[(kind.replace("BM_", "").lower(), m, n)] = b["real_time"] * scale
    return res


def fit(cells):
    """Least-squares c1, c2 of t = c1 m n + c2 m^3 over (m, n, t) cells."""
    a = np.array([[m * n, m**3] for m, n, _ in cells], float)
    t = np.array([c[2] for c in cells], float)
    w = 1.0 / t  # relative residuals
    c, *_ = np.linalg.lstsq(a * w[:, None], t * w, rcond=None)
    return float(c[0]), float(c[1])


def timing_grid(exes: dict, max_points: int, repeats: int) -> dict:
    """Seconds per image over the grid of Table I (up to ``max_points``
    points): the paper's figure, numpy's bank and joint filters, and each
    flight build of ``exes`` ({label: bench_modal path}; none: the flight
    filters through the bindings at 10 and 50 modes); with the least-squares
    fit of each source to the paper's cost model."""
    ns = [n for n in GRID_N if n <= max_points]
    flight = {}
    for label, exe in exes.items():
        print(f"flight grid, {label}: {exe} (9 repetitions per cell)", flush=True)
        flight[label] = run_bench_exe(exe)
    labels = list(exes) or ["flight"]
    rows = []
    for m in sorted(PAPER_TABLE):
        for j, n in enumerate(ns):
            row = {"modes": m, "points": n, "paper_s": PAPER_TABLE[m][j]}
            for kind in ("bank", "joint"):
                row[f"numpy_{kind}_s"] = mn.time_cell(m, n, kind, repeats=repeats)
                key = ("decoupled" if kind == "bank" else "joint", m, n)
                for label in exes:
                    if key in flight[label]:
                        row[f"{label}_{kind}_s"] = flight[label][key]
                if not exes and m in (10, 50):
                    row[f"flight_{kind}_bindings_s"] = flight_bindings(m, n, kind, repeats)
            for label in exes:
                if ("decomposition", m, n) in flight[label]:
                    row[f"{label}_decomposition_s"] = flight[label][("decomposition", m, n)]
            rows.append(row)
            cols = "".join(
                f"  {label} bank {_s(_cell(row, label, 'bank'))} joint {_s(_cell(row, label, 'joint'))}"
                for label in labels
            )
            print(
                f"m={m:2d} n={n:6d}  paper {_s(row['paper_s'])}  numpy bank {_s(row['numpy_bank_s'])} "
                f"joint {_s(row['numpy_joint_s'])}{cols}",
                flush=True,
            )
    out = {"rows": rows, "builds": exes, "paper_fit": {"c1": 1.4e-6, "c2": 3.6e-5}}
    for kind in ("bank", "joint"):
        for src in ["numpy"] + labels:
            cells = [(r["modes"], r["points"], _cell(r, src, kind)) for r in rows]
            cells = [c for c in cells if c[2] is not None]
            if len(cells) >= 2:
                out[f"fit_{src}_{kind}"] = dict(zip(("c1", "c2"), fit(cells)))
                print(
                    f"fit {src} {kind}: c1 = {out[f'fit_{src}_{kind}']['c1']:.3e} s, "
                    f"c2 = {out[f'fit_{src}_{kind}']['c2']:.3e} s"
                )
    return out


def _cell(row, src, kind):
    return row.get(f"{src}_{kind}_s", row.get(f"{src}_{kind}_bindings_s"))


def _s(v):
    if v is None:
        return "     -    "
    return f"{v * 1e3:9.3f}ms" if v >= 1e-3 else f"{v * 1e6:9.1f}us"
