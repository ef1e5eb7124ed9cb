"""Flying one effect's runs of a finished Basilisk campaign again
(bench/campaigns/gap/validate_basilisk.py refly), on the stored answers of the seed
2050 campaign with the diagnosis of each run stood in for: which runs are
flown, and the answers before and after counted run by run."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import pytest

from bench.campaigns.gap import validate_basilisk

STORED = Path(__file__).resolve().parents[2] / "docs/results/data/validate_gap_basilisk_8_seed2050.full.json.gz"


@pytest.fixture()
def campaign():
    with gzip.open(STORED, "rt") as f:
        return json.load(f)


def test_refly_flies_only_the_effects_runs_and_counts_the_answers(campaign, monkeypatch):
    flown = []

    def run_one(key, calibration):
        flown.append(key["run"])
        return {"run": key["run"], "gap_detected": True, "verdict": "unexplained", "top1": None, "map_max_abs_z": 9.0}

    monkeypatch.setattr(validate_basilisk, "run_one", run_one)
    res = validate_basilisk.refly(campaign, "flex_mode", calibration={}, progress=False)
    expected = [k["run"] for k in campaign["keys"] if k["effect"] == "flex_mode"]
    assert flown == expected and res["n"] == len(expected) >= 1
    before = {}
    for k, a in zip(campaign["keys"], campaign["answers"]):
        if k["effect"] == "flex_mode":
            said = a["verdict"] if a["gap_detected"] else "no_gap"
            before[said] = before.get(said, 0) + 1
    assert res["before"] == before and res["after"] == {"unexplained": len(expected)}
    assert res["runs"][0]["effects"] == campaign["keys"][expected[0]]["effects"]


def test_refly_of_an_effect_the_campaign_did_not_draw_is_refused(campaign):
    with pytest.raises(ValueError, match="no 'lens_distortion' run"):
        validate_basilisk.refly(campaign, "lens_distortion", calibration={}, progress=False)
