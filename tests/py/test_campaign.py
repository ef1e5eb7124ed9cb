"""The campaign machinery (bench/runner): records that read back bit for
bit, a store that resumes and keeps failures, and per-run results that do
not depend on the number of workers or on a resumed campaign."""

import json
import os

import numpy as np
import pytest

from bench.runner import records
from bench.runner.runner import Campaign, MissingRuns, failures, results
from bench.runner.store import RunStore

# Wall-clock fields: the only parts of a run's result that differ between two runs of it.
TIMING = ("t_sim_s", "t_diagnose_s", "elapsed_s")


def deterministic(obj):
    if isinstance(obj, dict):
        return {k: deterministic(v) for k, v in obj.items() if k not in TIMING}
    if isinstance(obj, list):
        return [deterministic(v) for v in obj]
    return obj


def test_records_read_back_bit_for_bit():
    rng = np.random.default_rng(5)
    obj = {
        "x": rng.normal(size=(3, 4)),
        "f32": rng.normal(size=5).astype(np.float32),
        "nan": float("nan"),
        "inf": -np.inf,
        "i": np.int64(7),
        "b": np.bool_(True),
        "s": np.array(["ok", "gated"]),
        "by_int": {1: 0.1 + 0.2, 2: [1, 2]},
        "tiny": 5e-324,
    }
    back = records.roundtrip(obj)
    assert back["x"].dtype == np.float64 and np.array_equal(back["x"].view(np.uint64), obj["x"].view(np.uint64))
    assert back["f32"].dtype == np.float32 and np.array_equal(back["f32"], obj["f32"])
    assert np.isnan(back["nan"]) and back["inf"] == -np.inf and back["tiny"] == 5e-324
    assert back["i"] == 7 and type(back["i"]) is int and back["b"] is True
    assert back["s"].tolist() == ["ok", "gated"]
    assert back["by_int"] == {1: 0.30000000000000004, 2: [1, 2]}
    assert records.sha256(obj) == records.sha256(back)


def _draw(item):
    if item["seed"] == 13:
        raise RuntimeError("this run fails")
    return {"seed": item["seed"], "v": np.random.default_rng(item["seed"]).normal(size=4)}


def test_store_resumes_keeps_failures_and_summarises(tmp_path, capsys):
    items = [{"seed": 10 + i} for i in range(6)]
    store = RunStore("unit", {"seed": 10}, root=tmp_path)
    with pytest.raises(MissingRuns):
        Campaign(store, summarise_only=True)
    half = [it if i < 3 else None for i, it in enumerate(items)]  # a campaign stopped after three runs
    first = Campaign(store, workers=1, progress=False).map("draw", _draw, half)
    assert [r is None for r in first] == [False] * 3 + [True] * 3
    assert sorted(os.listdir(store.path / "draw")) == [f"run-{i:06d}.json" for i in range(3)]
    assert failures(first) == []
    c = Campaign(store, workers=2, progress=True)
    recs = c.map("draw", _draw, items)
    assert c.stages["draw"] == {"runs": 6, "stored": 3, "ran": 3, "missing": 0}
    assert "3 of 6 runs already stored, skipping them; running 3" in capsys.readouterr().err
    fail = failures(recs)
    assert len(fail) == 1 and fail[0]["run"] == 3 and fail[0]["seed"] == 13 and "this run fails" in fail[0]["error"]
    stored = json.loads((store.path / "draw" / "run-000003.json").read_text())
    assert stored["ok"] is False and "Traceback" in stored["traceback"]
    # one worker, from nothing, in memory: the same records
    fresh = Campaign(None, workers=1, progress=False).map("draw", _draw, items)
    assert records.dumps(results(recs)) == records.dumps(results(fresh))
    # nothing left to run; the summary from the store alone; no temporary files
    again = Campaign(store, workers=1, progress=False)
    again.map("draw", _draw, items)
    assert again.stages["draw"]["ran"] == 0
    only = Campaign(store, summarise_only=True, progress=False).map("draw", _draw, items + [{"seed": 99}])
    assert only[-1] is None and records.dumps(results(only[:-1])) == records.dumps(results(recs))
    retry = Campaign(store, workers=1, progress=False, retry_failed=True)
    retry.map("draw", _draw, items)
    assert retry.stages["draw"]["ran"] == 1
    assert not [f for f in (store.path / "draw").iterdir() if f.name.startswith(".")]
    # a changed input is run again, not taken from the store
    changed = Campaign(store, workers=1, progress=False)
    changed.map("draw", _draw, [{"seed": 10 + i, "v": 2} for i in range(6)])
    assert changed.stages["draw"]["ran"] == 6


def test_null_calibration_is_identical_on_one_and_two_workers_and_resumed(tmp_path):
    from bench.campaigns.gap import null_calibration as null

    seeds = [int(s) for s in np.random.default_rng(11).integers(0, 2**31, 4)]
    one = null.calibrate(
        seeds, duration_s=40.0, campaign=Campaign(RunStore("n", {}, root=tmp_path / "a"), workers=1, progress=False)
    )
    store = RunStore("n", {}, root=tmp_path / "b")
    null.calibrate(seeds[:2], duration_s=40.0, campaign=Campaign(store, workers=2, progress=False))
    two = null.calibrate(seeds, duration_s=40.0, campaign=Campaign(store, workers=2, progress=False))
    for k in ("thresholds", "false_alarm_rate", "seeds", "null_map_max_abs_z", "null_screen_logp"):
        assert one[k] == two[k], k
    assert len(set(one["null_map_max_abs_z"])) == 4
