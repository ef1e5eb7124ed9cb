"""A campaign on a Dask cluster started by hand: `dask scheduler` and two
`dask worker` processes on 127.0.0.1, one of them killed while the campaign
runs. The store must end complete, each run once, and identical to the same
campaign run on one local worker."""

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from bench.campaigns.gap import validate
from bench.runner import records
from bench.runner.runner import Campaign
from bench.runner.store import RunStore

ROOT = Path(__file__).resolve().parents[2]
RUNS, DURATION_S, SEED = 6, 40.0, 3


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _dask_cli() -> list:
    exe = Path(sys.executable).with_name("dask")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "dask"]


def _wait_for_workers(address: str, n: int, timeout_s: float = 60.0) -> None:
    from distributed import Client

    with Client(address, timeout="20s") as c:
        c.wait_for_workers(n, timeout=timeout_s)


@pytest.fixture
def hand_started_cluster(tmp_path):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    procs = []

    def start(args, log):
        procs.append(
            subprocess.Popen(
                _dask_cli() + args,
                env=env,
                cwd=tmp_path,
                start_new_session=True,
                stdout=open(tmp_path / log, "w"),
                stderr=subprocess.STDOUT,
            )
        )
        return procs[-1]

    try:
        start(["scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"], "scheduler.log")
        workers = [
            start(
                [
                    "worker",
                    address,
                    "--host",
                    "127.0.0.1",
                    "--nthreads",
                    "1",
                    "--nworkers",
                    "1",
                    "--no-dashboard",
                    "--name",
                    f"w{i}",
                ],
                f"worker{i}.log",
            )
            for i in range(2)
        ]
        _wait_for_workers(address, 2)
        yield address, workers
    finally:
        from bench.runner import cluster

        cluster.close_all()
        for p in procs:  # every process this test started, and their children
            if p.poll() is None:
                try:
                    os.killpg(p.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            p.wait(timeout=30)


def _deterministic(recs: dict) -> dict:
    out = {}
    for i, r in recs.items():
        assert r["ok"], r.get("traceback")
        res = r["result"]
        out[i] = (
            {k: v for k, v in res.items() if k not in ("t_sim_s", "t_diagnose_s")} if isinstance(res, dict) else res
        )
    return out


def test_killed_worker_loses_and_duplicates_no_run(tmp_path, hand_started_cluster):
    address, workers = hand_started_cluster
    store = RunStore("validate-gap", {"runs": RUNS, "seed": SEED}, root=tmp_path / "cluster")
    killed = {}

    def kill_one_worker_mid_way():
        # after the second diagnosis is stored: the campaign is mid-way through its last stage
        t0 = time.time()
        while time.time() - t0 < 300:
            done = list((store.path / "diagnose").glob("run-*.json")) if (store.path / "diagnose").is_dir() else []
            if len(done) >= 2:
                os.killpg(workers[0].pid, signal.SIGKILL)
                killed["after"] = len(done)
                return
            time.sleep(0.05)

    watcher = threading.Thread(target=kill_one_worker_mid_way, daemon=True)
    watcher.start()
    res = validate.run_campaign(
        RUNS, SEED, None, duration_s=DURATION_S, campaign=Campaign(store, scheduler=address, progress=False)
    )
    watcher.join(timeout=5)
    assert 2 <= killed.get("after", RUNS) < RUNS, "the worker was not killed while runs remained"
    assert workers[0].poll() is not None
    assert res["campaign"]["runs_scored"] == RUNS and not res["campaign"]["failed_runs"]
    for stage in ("size", "diagnose"):
        files = sorted(p.name for p in (store.path / stage).iterdir())
        assert files == [f"run-{i:06d}.json" for i in range(RUNS)], stage  # each run once, no temporary files
    # the same campaign on one local worker, from nothing
    ref = RunStore("validate-gap", {"runs": RUNS, "seed": SEED}, root=tmp_path / "one")
    validate.run_campaign(RUNS, SEED, None, duration_s=DURATION_S, campaign=Campaign(ref, workers=1, progress=False))
    for stage in ("size", "diagnose"):
        a, b = _deterministic(store.load(stage)), _deterministic(ref.load(stage))
        assert records.dumps(a) == records.dumps(b), stage
