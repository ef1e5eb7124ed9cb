"""`make run`'s diagnosis of the bundled run: an ambiguous answer comes with
the valve plan that would separate its look-alikes (bench/commands/run.py,
docs/GAP.md "Designing the test that separates")."""

from __future__ import annotations

import json

from bench.commands.run import diagnose_bundled, plan_if_ambiguous


def test_the_bundled_ambiguous_answer_prints_the_plan_before_the_key(tmp_path, capsys):
    assert diagnose_bundled(tmp_path) == 0
    out = capsys.readouterr().out
    answer, plan, key = (out.index(s) for s in ("how far:", "plan it would fly:", "sealed key"))
    assert answer < plan < key  # designed from the answer alone, before the key is opened
    res = json.loads((tmp_path / "plan.json").read_text())
    assert res["hypotheses_from"].startswith("diagnosis")
    assert [h["set"] for h in res["hypotheses"]] == [["thrust_loss"], ["thrust_loss", "thruster_misalignment"]]
    d, f = res["designed"], res["fixed"]
    assert d["duration_s"] <= res["limits"]["max_duration_s"] and d["delta_v_mps"] <= res["limits"]["max_delta_v_mps"]
    # Each test printed with its distance on a half, the fixed plan's, the
    # level the diagnosis's test asks, and whether it passes.
    assert res["criterion"] == "selection"
    for pd, pf in zip(d["pairs"], f["pairs"]):
        assert f"{pd['a']} vs {pd['b']}: {pd['delta2_half']:.3g} on a half (fixed plan {pf['delta2_half']:.3g}" in out
        assert f"test asks {pd['required_half']:.3g}): " + ("passes" if pd["reached"] else "short of it") in out
    assert (tmp_path / "plan.png").stat().st_size > 10_000
    assert res["command"].startswith("proxops plan ") and "--separate --diagnosis" in res["command"]


def test_an_answer_that_is_not_ambiguous_gets_no_plan(tmp_path, capsys):
    for out in ({"verdict": "explained", "ambiguous_with": []}, {"verdict": "ambiguous", "ambiguous_with": []}, {}):
        plan_if_ambiguous(tmp_path / "log.h5", out, tmp_path)
    assert capsys.readouterr().out == ""
    assert not (tmp_path / "plan.json").exists()
