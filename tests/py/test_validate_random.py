"""The random-vehicle campaign (proxops validate-gap --vehicle random) end to
end, small and seeded: every run draws its own vehicle and Unix-epoch
clocks, its effect is sized against the calibration made for its own
flight (cached, so the diagnosis reuses it), keys are pre-registered and
scored. The mechanics, not the scores (docs/results/ records those)."""

import numpy as np

from bench.campaigns.gap import validate_random as vr
from bench.sim.log_description import resolve


def test_each_run_draws_a_vehicle_unlike_ours_on_a_unix_epoch():
    keys = vr.draw_campaign(10, seed=5)
    seeds = {k["vehicle_seed"] for k in keys}
    assert len(seeds) == 10
    masses = [resolve(vr.description_of(k)).mass_kg for k in keys]
    assert min(masses) >= 2.0 and max(masses) <= 50.0 and np.std(masses) > 1.0
    assert all(vr.clocks_of(k).epoch_s > 1.6e9 for k in keys)
    k = (
        next(k for k in keys if k["effect"] == "thrust_loss")
        if any(k["effect"] == "thrust_loss" for k in keys)
        else None
    )
    if k is not None:  # a per-valve effect is drawn for the run's own number of valves
        assert len(k["unit"]) == resolve(vr.description_of(k)).n_thrusters
    assert vr.draw_campaign(10, seed=5) == keys  # seeded


def test_a_small_campaign_runs_end_to_end(tmp_path, monkeypatch):
    monkeypatch.setenv("PROXOPS_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "vr.json"
    res = vr.run_campaign(2, seed=11, out=str(out), workers=1, progress=False, null_runs=6)
    assert (tmp_path / "vr.json.prereg.json").exists()
    assert res["keys_match_preregistration"] and res["runs"] == 2 and len(res["answers"]) == 2
    assert all(
        a["verdict"] in ("no_gap", "explained", "ambiguous", "unexplained", "partly_explained") for a in res["answers"]
    )
    assert res["first_answer_s"]["max"] > 0.0
    assert all(a["gap_detected"] == (a["verdict"] != "no_gap") for a in res["answers"])


def test_the_detection_limit_is_measured_on_the_engine_that_flies_the_run(monkeypatch):
    """A Basilisk run is sized on Basilisk's flights of it (its slosh and
    hinged panel move a vehicle otherwise than the bench's), calibrated on
    Basilisk's effect-free flight."""
    from bench.campaigns.gap import detectable
    from bench.gap import log_null

    key = next(k for k in vr.draw_campaign(10, 3403, "basilisk") if k["effect"] is not None)
    flown = []

    def fake_simulate(k, effects=None, engine=None):
        flown.append((engine or k["engine"], effects))
        return "log"

    def fake_search(seed, name, unit, duration, cal, simulate=None, max_size=None, **kw):
        simulate({name: [0.0]})
        return {"size": 1e-3, "detectable": True, "lambda_at_size": 1.0}

    monkeypatch.setattr(vr, "simulate_key", fake_simulate)
    monkeypatch.setattr(detectable, "min_detectable_size", fake_search)
    monkeypatch.setattr(log_null, "calibrate_for_log", lambda log, **kw: {"thresholds": {}})
    sized = vr.size_one(key)
    assert [e for e, _ in flown] == ["basilisk", "basilisk"] and flown[0][1] == {}
    assert sized["min_detectable"] == 1e-3 and sized["effects"]
