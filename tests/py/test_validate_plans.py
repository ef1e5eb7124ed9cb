"""The designed plans' campaign (``proxops validate-gap --plans``): the plan
as the docking engine's valve scripts, the scoring of an answer after the
plan, the draws taken from a recorded campaign, and one ambiguous docking
run taken end to end on a fixed seed."""

import json

import pytest

from bench.campaigns.gap import validate_plans as vp


def test_plan_runs_become_valve_scripts_of_the_docking_engine():
    plan = {
        "schedule": [
            {"valves": {"3": [[2.0, 3.0]]}, "duration_s": 13.0},
            {"valves": {"0": [[2.0, 2.5]]}, "duration_s": 4.5},
        ]
    }
    a, b = vp.plan_scripts(plan)
    assert len(a) == 130 and a[:20] == [0] * 20 and a[20:30] == [8] * 10 and a[30:] == [0] * 100
    assert len(b) == 45 and b[20:25] == [1] * 5 and sum(b) == 5


def _pub(verdict, named, listed=()):
    return {
        "gap_detected": verdict != "no_gap",
        "verdict": verdict,
        "effects": [{"effect": n} for n in named],
        "ambiguous_with": [{"set": list(s)} for s in listed],
    }


def test_an_answer_is_exact_listed_or_settled():
    key = {"members": ["thrust_loss", "thruster_misalignment"]}
    both = ["thruster_misalignment", "thrust_loss"]
    a = vp.answer_of(_pub("ambiguous", ["thrust_loss"], [both]), key)
    assert (a["exact"], a["listed"], a["settled"]) == (False, True, False)
    a = vp.answer_of(_pub("ambiguous", both, [["thrust_loss"]]), key)
    assert (a["exact"], a["listed"], a["settled"]) == (True, True, False)
    a = vp.answer_of(_pub("explained", both), key)
    assert (a["exact"], a["listed"], a["settled"]) == (True, True, True)
    a = vp.answer_of(_pub("explained", both + ["clock_drift"]), key)
    assert (a["exact"], a["listed"]) == (False, False)
    # an out-of-library member is not the library's to name
    a = vp.answer_of(_pub("partly_explained", ["thrust_loss"]), {"members": ["thrust_loss", "fuel_slosh"]})
    assert a["settled"]
    assert not vp.answer_of(_pub("no_gap", []), key)["listed"]


def test_recorded_campaign_gives_its_detectable_2x_runs(tmp_path):
    keys = [
        {"run": 0, "scale": 2.0, "members": ["gyro_bias"], "effects": {"gyro_bias": [1e-3, 0, 0]}},
        {"run": 1, "scale": 1.0, "members": ["gyro_bias"], "effects": {"gyro_bias": [1e-3, 0, 0]}},
        {"run": 2, "scale": 2.0, "members": ["gyro_bias"], "effects": {"gyro_bias": [0, 0, 0]}, "detectable": False},
        {"run": 3, "scale": 2.0, "members": ["accel_bias"], "effects": {"accel_bias": [1e-3, 0, 0]}},
    ]
    p = tmp_path / "rec.json"
    p.write_text(json.dumps({"keys": keys}))
    got = vp.recorded_keys([p])
    assert [(k["run"], k["recorded_run"], k["source"]) for k in got] == [(0, 0, "rec.json"), (1, 3, "rec.json")]
    # a recorded key keeps its sizes: sizing does not run again
    assert vp.size_key(got[1], None) is got[1]
    p.write_text(json.dumps({"keys": keys, "manoeuvres": "docking+characterisation"}))
    with pytest.raises(ValueError, match="appended to docking logs"):
        vp.recorded_keys([p])


def test_scores_fall_back_to_the_answer_when_no_plan_was_designed():
    key = {"run": 0, "kind": "pair", "members": ["thrust_loss", "thruster_misalignment"]}
    before = dict(vp.answer_of(_pub("ambiguous", ["thrust_loss"], [["thrust_loss", "thruster_misalignment"]]), key))
    after = vp.answer_of(_pub("explained", ["thrust_loss", "thruster_misalignment"]), key)
    plan = {"run": 0, "plans": {}, "null": {"gap_detected": True}, "after": after, "designed": True}
    row = {
        "duration_s": 60.0,
        "delta_v_mps": 0.08,
        "delta2_min": 12.0,
        "level_min": 1.2,
        "continuous_level_min": 1.5,
        "target_reached": True,
        "short": [],
    }
    plan["plans"] = {"designed": row, "half": row, "fixed": dict(row, duration_s=200.0, delta_v_mps=0.16)}
    plan["needed"] = {"limits": [1200.0, 1.6], "level_max": 0.5, "reached": False}
    members = [{"member": "thrust_loss", "delta2_half": 60.0, "required_half": 46.2, "reached": True}]
    short = [dict(members[0], delta2_half=30.0, reached=False)]
    plan["flown_true"] = {
        "designed": {"flown": True, "delta2_min": 20.0, "members": members},
        "half": {"flown": True, "delta2_min": 20.0, "members": members + short},
        "fixed": {"flown": False, "members": members},
    }
    none = {"run": 1, "designed": False, "why": "the diagnosis names no effect"}
    s = vp.score_plans([key, dict(key, run=1)], [before, before], [plan, none], [])
    assert s["kept"] == 2 and s["designed"] == 1
    assert s["settled_after"]["k"] == 1 and s["listed_after"]["k"] == 2
    assert s["false_alarms"] == {"n": 1, "k": 1, "fraction": 1.0}
    dist = s["distances"]
    assert dist["listed_reach_flown"]["designed"]["k"] == 1 and dist["listed_reach_flown"]["fixed"]["n"] == 0
    # every true member's selection test at its level: one short of it on the half plan
    assert [dist["members_reached_flown"][k]["k"] for k in ("designed", "half", "fixed")] == [1, 0, 1]
    assert dist["designed_reach_predicted"]["k"] == 1 and dist["needed_reach_continuous"]["k"] == 0
    assert dist["half_duration_share_median"] == pytest.approx(0.3)
    assert s["not_designed"] == [{"run": 1, "why": "the diagnosis names no effect"}]


def test_an_ambiguous_docking_run_is_settled_by_its_plan_and_a_clean_flight_raises_no_gap():
    """A thrust loss on two valves beside a gyro bias, at 2x their sizes, on
    one docking log (seed 7): answered with both, ambiguous with a nozzle
    tilt beside them. The plan designed from that answer, appended to the
    docking log with the same effects, settles it (both named, nothing
    listed); appended to the same docking seed without effects, no gap."""
    from bench.gap import null as nullmod

    effects = {"thrust_loss": [0.0, 0, 0, 0.06, 0, 0, 0.05, 0], "gyro_bias": [2e-3, -1.5e-3, 1e-3]}
    key = {"run": 0, "seed": 7, "kind": "pair", "members": sorted(effects), "effects": effects}
    shared = (120.0, nullmod.load())
    a = vp.diagnose_docking(key, shared)
    assert a["kept"] and a["verdict"] == "ambiguous" and a["exact"] and not a["settled"]
    assert a["alternatives"] == [["gyro_bias", "thrust_loss", "thruster_misalignment"]]
    p = vp.plan_run((key, a), shared)
    assert p["designed"] and p["hypotheses"] == [
        "thrust_loss + gyro_bias",
        "thrust_loss + gyro_bias + thruster_misalignment",
    ]
    assert p["after"]["settled"] and p["after"]["verdict"] == "explained"
    assert not p["null"]["gap_detected"]
    # the default plan: two passes within 120 s and the fixed plan's delta-v
    d, f = p["plans"]["designed"], p["plans"]["fixed"]
    assert d["duration_s"] <= 120.0 and d["delta_v_mps"] <= f["delta_v_mps"] + 1e-9 and f["duration_s"] == 200.0
    # within half the fixed plan, a tilt along any direction at the listed size is not told apart
    assert (
        not p["plans"]["half"]["target_reached"] and p["plans"]["half"]["delta_v_mps"] <= 0.5 * f["delta_v_mps"] + 1e-9
    )
    # every other listed set holds the true set: no flown distance to measure
    assert not p["flown_true"]["designed"]["flown"]


def test_an_unexplained_answer_is_designed_for_the_sets_it_lists():
    listed = {"ambiguous_with": [{"set": ["gyro_scale"]}, {"set": ["gyro_scale", "thrust_loss"]}]}
    assert vp.listed_of_unexplained({"verdict": "unexplained", **listed}) == [
        ["gyro_scale"],
        ["gyro_scale", "thrust_loss"],
    ]
    # one listed set is nothing to separate; an answer with a set designs from that set
    assert vp.listed_of_unexplained({"verdict": "unexplained", "ambiguous_with": [{"set": ["gyro_scale"]}]}) is None
    assert vp.listed_of_unexplained({"verdict": "ambiguous", **listed}) is None


def test_the_basilisk_subset_is_spread_over_the_runs_its_engine_flies():
    kept = [({"effects": {"gyro_bias": [0, 0, 0]}}, {}) for _ in range(9)]
    kept[1] = ({"effects": {"clock_drift": [1e-5]}}, {})
    assert vp.basilisk_subset(kept, 3) == {0, 3, 5}
    assert vp.basilisk_subset(kept, 0) == set() and len(vp.basilisk_subset(kept, 20)) == 8


def test_a_true_members_test_is_found_whatever_order_a_listed_set_names_it(monkeypatch):
    """The true set's test of each member is its distance from the set
    without it; a listed set may name those members in another order."""
    from bench.gap import design as D

    def flown(description, segs, hyps, truth, seed):
        A = hyps[truth]
        pairs = [{"a": A.name, "b": h.name, "delta2": 100.0 + i} for i, h in enumerate(hyps) if i != truth]
        return {"lambda": 1.0, "pairs": pairs}

    monkeypatch.setattr(D, "flown_distances", flown)
    monkeypatch.setattr(D, "plan_segments", lambda plan, n: [])
    effects = {"com_offset": [0.01, 0, 0], "thrust_loss": [0.05] + [0.0] * 7, "thruster_misalignment": [0.0] * 24}
    key = {"seed": 1, "members": sorted(effects), "effects": effects}
    listed = [D.Hypothesis(["thruster_misalignment", "com_offset"], {}), D.Hypothesis(["thrust_loss"], {})]
    f = vp.flown_true(key, {"vehicle": {"thrusters": [{}] * 8}}, {}, listed, None)
    assert [m["member"] for m in f["members"]] == vp.truth_in(key)
    # the set without thrust_loss is the first listed one, named the other way round
    without_loss = next(m for m in f["members"] if m["member"] == "thrust_loss")
    assert without_loss["delta2_half"] == 0.5 * 101.0
    assert f["pairs"][0] == {"b": "thruster_misalignment + com_offset", "delta2": 101.0}
