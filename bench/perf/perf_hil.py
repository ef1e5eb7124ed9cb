"""Real-time factor of the docking scenario, side by side in one process:
in-process (the filter through the bindings) and lockstep over the
pseudo-terminal link with fsw_node (clean link), on the same seeds.

Each repetition runs `--duration` simulated seconds of chained docking runs
both ways; the table gives the median and spread over repetitions, and the
link's step latency (send to the step's last telemetry packet).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python -m bench.perf.perf_hil [--duration 300] [--repeat 5] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from bench.sim.scenario_docking import ScenarioConfig, run_docking  # noqa: E402
from hil_sim.run import HilConfig, run_hil  # noqa: E402


def in_process_rtf(duration_s: float, seed: int) -> float:
    """Chains docking runs in-process exactly as run_hil does over the link."""
    t_done, k = 0.0, 0
    t0 = time.perf_counter()
    while t_done < duration_s - 1e-9:
        sc = ScenarioConfig(t_max_s=min(ScenarioConfig().t_max_s, duration_s - t_done))
        run = run_docking(seed + k, sc)
        t_done += float(run.summary.t_end_s) + sc.dt_s
        k += 1
    return t_done / (time.perf_counter() - t0)


def cpu_model() -> str:
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
        for line in out.splitlines():
            if line.startswith("Model name"):
                return line.split(":", 1)[1].strip()
    except (OSError, subprocess.CalledProcessError):
        pass
    return platform.processor() or "unknown"


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=300.0, help="simulated seconds per repetition")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", default=None)
    ap.add_argument("--learner", action="store_true", help="valve commands and tm_learner on the link too")
    args = ap.parse_args(argv)

    rows = []
    for i in range(args.repeat):
        rtf_in = in_process_rtf(args.duration, args.seed)
        res = run_hil(HilConfig(duration_s=args.duration, seed=args.seed, learner=args.learner))
        rows.append(
            {
                "in_process_rtf": rtf_in,
                "link_rtf": res["real_time_factor"],
                "p50_ms": res["step_latency_p50_ms"],
                "p99_ms": res["step_latency_p99_ms"],
                "steps": res["steps"],
                "timeouts": res["step_timeouts"],
            }
        )
        print(
            f"rep {i + 1}/{args.repeat}: in-process RTF {rtf_in:6.1f}   link RTF {res['real_time_factor']:6.1f}"
            f"   step latency p50 {res['step_latency_p50_ms']:.3f} ms p99 {res['step_latency_p99_ms']:.3f} ms",
            flush=True,
        )

    def med(key):
        return float(np.median([r[key] for r in rows]))

    out = {
        "machine": {"cpu": cpu_model(), "cores": os.cpu_count(), "python": platform.python_version()},
        "duration_s": args.duration,
        "repeat": args.repeat,
        "seed": args.seed,
        "learner": bool(args.learner),
        "in_process_rtf_median": med("in_process_rtf"),
        "link_rtf_median": med("link_rtf"),
        "link_rtf_min": float(min(r["link_rtf"] for r in rows)),
        "step_latency_p50_ms_median": med("p50_ms"),
        "step_latency_p99_ms_median": med("p99_ms"),
        "rows": rows,
    }
    print(
        f"\nmedian over {args.repeat}: in-process RTF {out['in_process_rtf_median']:.1f}, "
        f"lockstep over the link RTF {out['link_rtf_median']:.1f} (min {out['link_rtf_min']:.1f}); "
        f"step latency p50 {out['step_latency_p50_ms_median']:.3f} ms, p99 {out['step_latency_p99_ms_median']:.3f} ms"
    )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=2)
    return out


if __name__ == "__main__":
    main()
