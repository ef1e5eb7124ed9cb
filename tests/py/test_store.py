"""A campaign's results store read back: a record of the wrong shape or
whose result was edited (null, [], {}, an index of Infinity, a result that
no longer matches its hash) counts as not stored, so the summary lists that
run as missing (or it runs again) instead of crashing or silently leaving it
out of both failed_runs and missing_runs."""

from __future__ import annotations

import json

import pytest

from bench.runner import cluster, records
from bench.runner.runner import Campaign, failures, missing, results
from bench.runner.store import RunStore

STAGE = "s"
IDENTS = [{"seed": i} for i in range(4)]


def _square(x):
    return {"x": x, "y": x * x}


@pytest.fixture
def stored(tmp_path, monkeypatch):
    """A store with four finished runs (run in this process: no cluster)."""
    monkeypatch.setattr(cluster, "inside_worker", lambda: True)
    store = RunStore("t", {"a": 1}, root=tmp_path)
    recs = Campaign(store, progress=False).map(STAGE, _square, list(range(4)), idents=IDENTS)
    assert [r["ok"] for r in recs] == [True] * 4
    return store


def _summary(store):
    recs = Campaign(RunStore("t", {"a": 1}, root=store.path.parent), progress=False, summarise_only=True).map(
        STAGE, _square, list(range(4)), idents=IDENTS
    )
    return results(recs), failures(recs), missing(recs)


def test_a_finished_run_stores_the_hash_of_its_result(stored):
    rec = json.loads((stored.path / STAGE / "run-000001.json").read_text())
    assert rec["result_sha256"] == records.sha256(rec["result"])
    assert _summary(stored) == ([_square(i) for i in range(4)], [], [])


def _edit_result(value):
    def edit(rec):
        rec["result"] = value
        return rec

    return edit


def _legacy(value):
    """A record written before results were hashed."""

    def edit(rec):
        rec.pop("result_sha256")
        rec["result"] = value
        return rec

    return edit


DAMAGED = [
    ("result null", _edit_result(None)),
    ("result []", _edit_result([])),
    ("result {}", _edit_result({})),
    ("result edited", _edit_result({"x": 1, "y": 2})),
    ("legacy result null", _legacy(None)),
    ("legacy result {}", _legacy({})),
    ("legacy result []", _legacy([])),
    ("no result", lambda rec: {k: v for k, v in rec.items() if k != "result"}),
    ("whole record []", lambda rec: []),
    ("whole record null", lambda rec: None),
    ("index Infinity", lambda rec: {"index": float("inf")}),
    ("index of another run", lambda rec: dict(rec, index=3)),
    ("index a string", lambda rec: dict(rec, index="1")),
    ("ok not a boolean", lambda rec: dict(rec, ok="yes")),
    ("no input hash", lambda rec: {k: v for k, v in rec.items() if k != "input_sha256"}),
]


@pytest.mark.parametrize("what, edit", DAMAGED, ids=[d[0] for d in DAMAGED])
def test_a_damaged_record_counts_as_missing(stored, what, edit):
    f = stored.path / STAGE / "run-000001.json"
    f.write_text(json.dumps(edit(json.loads(f.read_text())), allow_nan=True))
    res, failed, miss = _summary(stored)
    assert miss == [1] and failed == [] and res[1] is None
    assert res[0] == _square(0) and res[2:] == [_square(2), _square(3)]


def test_a_damaged_record_is_run_again(stored):
    f = stored.path / STAGE / "run-000002.json"
    f.write_text("[]")
    recs = Campaign(RunStore("t", {"a": 1}, root=stored.path.parent), progress=False).map(
        STAGE, _square, list(range(4)), idents=IDENTS
    )
    assert results(recs) == [_square(i) for i in range(4)] and missing(recs) == []
    assert json.loads(f.read_text())["index"] == 2
