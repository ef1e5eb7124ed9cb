"""What a team's own vehicle waits for: the first answer of `proxops diagnose`
for a new vehicle's log (its null calibration made, 40 simulated flights,
from an empty cache), the second answer for another log of the same vehicle
and plan, and one navigation replay of the log, stepped from Python beside
the one-call replay in the flight code, in one run:

    OPENBLAS_NUM_THREADS=1 .venv/bin/python -m bench.perf.perf_gap [--vehicle-seed 3] [--minutes 10]
        [--repeats 3] [--replay-repeats 9] [--profile 25] [--keep DIR] [--json OUT]

The vehicle is ``bench.sim.random_vehicle.random_description(seed)`` with
its clocks (``random_clocks``: IMU jitter and drops, pose phase and jitter,
a Unix epoch), flying ``bench.sim.plans.characterisation_plan`` runs until
``--minutes`` of flight; two logs of it (sensor noise seeds 1 and 2) are
written with the flight-log writer. Each first answer is the command
``proxops diagnose LOG_1`` with ``PROXOPS_CACHE`` an empty folder; the
second answer is ``proxops diagnose LOG_2`` with the first's cache (when the
calibration is not taken from the cache for it, the run says so and the
second answer is also timed with the first's calibration supplied as the
vehicle's, ``--calibration``). Wall and CPU time (the command and its
worker processes) are medians over ``--repeats``; the replay's over
``--replay-repeats`` (wall and this process's CPU). ``--profile N`` adds
cProfile's top N entries (cumulative time) of one null run of the
calibration, its flight made and then reused, and of the second answer.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.report import write_json


def new_vehicle_logs(seed: int, minutes: float, folder: Path, noise_seeds=(1, 2)) -> list:
    """Paths of the logs (one per noise seed) of vehicle ``seed`` flying
    characterisation runs for ``minutes``."""
    from bench.sim.flight_log import write_flight_log
    from bench.sim.plans import characterisation_plan
    from bench.sim.random_vehicle import random_clocks, random_description
    from bench.sim.vehicle_sim import simulate

    desc = random_description(seed)
    clocks = random_clocks(seed, desc["imu"]["rate_hz"])
    plan, s = [], 0
    while sum(p.duration_s + clocks.gap_s for p in plan) < 60.0 * minutes:
        for p in characterisation_plan(desc, seed=s):
            if sum(q.duration_s + clocks.gap_s for q in plan) < 60.0 * minutes:
                plan.append(p)
        s += 1
    paths = []
    for n in noise_seeds:
        log, _ = simulate(desc, plan, {}, seed=n, clocks=clocks, with_truth=False)
        log.config = {}
        paths.append(write_flight_log(folder / f"vehicle{seed}_noise{n}.h5", log))
    return paths


def _median(rows: list, key: str) -> float:
    return float(np.median([r[key] for r in rows]))


def time_replay(path: Path, repeats: int) -> dict:
    """Median wall and CPU time of one navigation replay of the log (after
    its reference), stepped from Python and in one call, alternated."""
    from bench.gap.load import prepare
    from bench.gap.replay import reference, replay
    from bench.perf.nav_replay_stepped import stepped
    from bench.sim.flight_log import read_flight_log

    d = prepare(read_flight_log(path))
    reference(d)
    rows = {"python_stepped": [], "one_call": []}
    same = True
    for _ in range(repeats):
        for name, fn in (("python_stepped", stepped), ("one_call", replay)):
            w0, c0 = time.perf_counter(), time.process_time()
            res = fn(d)
            rows[name].append({"wall_s": time.perf_counter() - w0, "cpu_s": time.process_time() - c0})
            if name == "one_call":
                ref = stepped(d)
                same = same and np.array_equal(res.nis, ref.nis) and np.array_equal(res.innovation, ref.innovation)
    out = {k: {"wall_s": _median(v, "wall_s"), "cpu_s": _median(v, "cpu_s")} for k, v in rows.items()}
    out.update(imu_samples=int(d.imu_t.size), poses=int(d.pose_tc.size), identical=bool(same))
    for k in ("python_stepped", "one_call"):
        out[k]["cpu_us_per_imu_sample"] = 1e6 * out[k]["cpu_s"] / d.imu_t.size
    return out


def run_diagnose(log: Path, cache: Path, out: Path, extra=()) -> dict:
    """`proxops diagnose LOG` as a user runs it: wall and CPU time (with its
    worker processes) and the answer's calibration note."""
    env = dict(os.environ, PROXOPS_CACHE=str(cache))
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    cmd = [sys.executable, "-m", "bench.cli", "diagnose", str(log), "--json", str(out), "--quiet", *extra]
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    ans = json.loads(out.read_text())
    cal = ans.get("calibration") or {}
    return {
        "wall_s": wall,
        "cpu_s": (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime),
        "verdict": ans.get("verdict"),
        "calibration_source": cal.get("source"),
        "calibration_from_cache": bool(cal.get("from_cache")),
        "calibration_elapsed_s": cal.get("elapsed_s"),
    }


def made_calibrations(cache: Path) -> list:
    return sorted((cache / "null_calibration").glob("*.json"))


def vehicle_calibration(made: Path, log: Path, out: Path) -> Path:
    """The calibration ``made`` for ``log`` as a calibration of its vehicle
    and manoeuvres, for ``--calibration``."""
    from bench.sim.flight_log import read_flight_log

    cal = json.loads(made.read_text())
    desc = dict(read_flight_log(log).description or {})
    desc.pop("segments", None)
    keep = {
        k: cal[k]
        for k in ("thresholds", "tail", "null_map_max_abs_z", "null_screen_logp", "runs", "seed", "method")
        if k in cal
    }
    keep["false_alarm_target_each"] = cal["false_alarm_target_each"]
    out.write_text(json.dumps(dict(keep, description=desc, manoeuvres="characterisation"), indent=1) + "\n")
    return out


def answers(logs: list, repeats: int, folder: Path) -> dict:
    """First answers (each from an empty cache) and second answers."""
    first, second, supplied = [], [], []
    for i in range(repeats):
        cache = folder / f"cache{i}"
        first.append(run_diagnose(logs[0], cache, folder / f"first{i}.json"))
        made = made_calibrations(cache)
        second.append(run_diagnose(logs[1], cache, folder / f"second{i}.json"))
        if not second[-1]["calibration_from_cache"] and len(made) == 1:
            cal = vehicle_calibration(made[0], logs[0], folder / f"vehicle_calibration{i}.json")
            supplied.append(run_diagnose(logs[1], cache, folder / f"supplied{i}.json", ("--calibration", str(cal))))
    out = {"first": first, "second": second}
    if supplied:
        out["second_calibration_supplied"] = supplied
    for k in list(out):
        out[k + "_median"] = {m: _median(out[k], m) for m in ("wall_s", "cpu_s")}
    return out


def profile_top(fn, top: int) -> str:
    import cProfile
    import io
    import pstats

    pr = cProfile.Profile()
    pr.enable()
    fn()
    pr.disable()
    s = io.StringIO()
    pstats.Stats(pr, stream=s).sort_stats("cumulative").print_stats(top)
    return s.getvalue()


def profiles(logs: list, top: int, cal_path: Path | None) -> dict:
    """cProfile of one null run of the calibration for the first log (its
    flight made, then made again or reused) and of the second answer (with
    ``cal_path``, else from the cache PROXOPS_CACHE names)."""
    from bench.gap import log_null
    from bench.gap.detection import null_statistics
    from bench.gap.diagnose import diagnose
    from bench.sim.flight_log import read_flight_log

    log = read_flight_log(logs[0])
    prepared = log_null.plan_of(log)
    out = {}
    for key, seed in (("null_run_first", 101), ("null_run_next", 102)):
        out[key] = profile_top(lambda s=seed: null_statistics(log_null.null_log_like(log, s, prepared)), top)
    second = read_flight_log(logs[1])
    if cal_path is not None:  # the vehicle's calibration supplied
        cal = json.loads(cal_path.read_text())
        out["second_answer"] = profile_top(lambda: diagnose(second, calibration=cal, calibration_source="perf"), top)
    else:  # the first answer's cache (PROXOPS_CACHE) holds it
        out["second_answer"] = profile_top(lambda: diagnose(second), top)
    return out


def machine() -> dict:
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu, "nproc": os.cpu_count(), "python": platform.python_version(), "numpy": np.__version__}


def _commit() -> str:
    root = Path(__file__).resolve().parents[2]
    try:
        return subprocess.run(
            ["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def report(out: dict) -> None:
    m = out["machine"]
    print(f"{m['cpu']}; nproc {m['nproc']}; load average {out['loadavg_before']} -> {out['loadavg_after']}")
    print(f"vehicle seed {out['seed']}, {out['minutes']} min of characterisation runs; commit {out['commit']}")
    print(f"{'':44s} {'wall [s]':>10s} {'CPU [s]':>10s}")
    rp = out.get("replay")
    if rp is not None:
        print(f"one replay of the log: {rp['imu_samples']} IMU samples, {rp['poses']} poses")
        for k, title in (("python_stepped", "  stepped from Python"), ("one_call", "  one call (nav_replay)")):
            print(f"{title:44s} {rp[k]['wall_s']:10.4f} {rp[k]['cpu_s']:10.4f}")
        print(f"{'':44s} identical results: {rp['identical']}")
    a = out["answers"]
    for k, title in (
        ("first", "first answer (calibration made)"),
        ("second", "second answer (same cache)"),
        ("second_calibration_supplied", "second answer (calibration supplied)"),
    ):
        if k in a:
            med = a[k + "_median"]
            print(f"{title:44s} {med['wall_s']:10.1f} {med['cpu_s']:10.1f}   ({len(a[k])} runs, medians)")
    if "second_calibration_supplied" in a:
        print("note: the second log's calibration was not taken from the cache (its fingerprint differs)")
    for k, text in out.get("profiles", {}).items():
        print(f"\n--- profile: {k}\n{text}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vehicle-seed", type=int, default=3)
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--repeats", type=int, default=3, help="first and second answers")
    ap.add_argument("--replay-repeats", type=int, default=9, help="0: no replay timing")
    ap.add_argument("--profile", type=int, default=0, help="top N cProfile entries (0: no profile)")
    ap.add_argument("--keep", default=None, help="keep the logs, caches and answers in this folder")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    out = {
        "command": " ".join(
            [sys.executable, "-m", "bench.perf.perf_gap"] + (argv if argv is not None else sys.argv[1:])
        ),
        "commit": _commit(),
        "machine": machine(),
        "seed": a.vehicle_seed,
        "minutes": a.minutes,
        "loadavg_before": [round(x, 2) for x in os.getloadavg()],
    }
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(a.keep) if a.keep else Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        logs = new_vehicle_logs(a.vehicle_seed, a.minutes, folder)
        if a.replay_repeats > 0:
            out["replay"] = time_replay(logs[0], a.replay_repeats)
        out["answers"] = answers(logs, a.repeats, folder)
        if a.profile > 0:
            cal = folder / "vehicle_calibration0.json"
            os.environ["PROXOPS_CACHE"] = str(folder / "cache0")
            out["profiles"] = profiles(logs, a.profile, cal if cal.exists() else None)
    out["loadavg_after"] = [round(x, 2) for x in os.getloadavg()]
    report(out)
    if a.json:
        write_json(a.json, out)


if __name__ == "__main__":
    main()
