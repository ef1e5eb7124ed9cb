"""Several effects at once: forward selection names every effect the data
support, refitted jointly, each member with its share; one effect alone
stays one."""

import numpy as np
import pytest

from bench.campaigns.gap.validate import blind
from bench.gap import null as nullmod
from bench.gap.diagnose import diagnose, public

reality = pytest.importorskip("bench.sim.reality")


def _answer(seed, effects, full=False):
    log, _ = reality.simulate_log_with_key(seed, effects, duration_s=120.0, with_truth=False)
    res = diagnose(blind(log), calibration=nullmod.load())
    return res if full else public(res)


def test_thrust_loss_and_gyro_bias_are_both_named(tmp_path):
    from bench.gap.answers import answer_lines
    from bench.gap.report import write_report

    full = _answer(7, {"thrust_loss": [0.0, 0, 0, 0.06, 0, 0, 0.05, 0], "gyro_bias": [2e-3, -1.5e-3, 1e-3]}, True)
    r = public(full)
    assert sorted(m["effect"] for m in r["effects"]) == ["gyro_bias", "thrust_loss"]
    # A docking approach cannot rule out a nozzle tilt of the same valves
    # beside the loss: the one set listed is the answer with the tilt.
    assert r["verdict"] == "ambiguous"
    assert [sorted(a["set"]) for a in r["ambiguous_with"]] == [["gyro_bias", "thrust_loss", "thruster_misalignment"]]
    es = r["effect_set"]
    assert es["explains_heldout"] and es["every_member_needed"] and es["shrink_heldout"]["fraction"] > 0.8
    gb = next(m for m in r["effects"] if m["effect"] == "gyro_bias")["parameters"]
    fitted = np.array([v["value"] for v in gb.values()])
    sig = np.array([v["sigma"] for v in gb.values()])
    assert np.all(np.abs(fitted - [2e-3, -1.5e-3, 1e-3]) < 4 * sig + 1e-4)
    # each member adds to the held-out likelihood beside the other
    assert all(m["adds_dll_heldout"] > 3.0 for m in r["effects"])
    text = "\n".join(t for _, t in answer_lines(r))
    assert "thrust_loss + gyro_bias (ambiguous, together; cannot be told from: " in text and "adds" in text
    # The losses of valves 5 and 7, held at 0 by the bounded fit (4e-15 and
    # 1e-14), are at the bound, with no sigma, never beyond 2 sigma; the
    # others' sigmas come with them held, alike in the set and alone.
    loss = next(m for m in r["effects"] if m["effect"] == "thrust_loss")["parameters"]
    assert {k for k, v in loss.items() if v.get("at_bound") == "lower"} == {"loss_5 [1]", "loss_7 [1]"}
    assert loss["loss_5 [1]"]["sigma"] is None
    assert "thrust_loss: loss_3 [1] 0.0616 +/- 0.0036, loss_6 [1] 0.0502 +/- 0.0032 (at the lower bound 0: " in text
    alone = next(a for a in r["attribution"] if a["effect"] == "thrust_loss")["parameters"]
    assert alone["loss_3 [1]"]["sigma"] == pytest.approx(loss["loss_3 [1]"]["sigma"], rel=1e-3)
    page = write_report(full, tmp_path, "mixture").read_text()
    assert "RMS on held-out rows, nominal -> with thrust_loss + gyro_bias" in page
    # the set's members with their shares and jointly fitted parameters
    assert "## The selected set: thrust_loss + gyro_bias" in page
    members = page.split("## The selected set")[1].split("## Ranking")[0]
    assert "| thrust_loss | dynamics |" in members and "| gyro_bias | sensor |" in members
    assert "loss_3 [1] = " in members and "b_x [rad/s] = " in members
    # the channel shown is where the gap map found the gap, not the one an effect of the set acts on
    assert "Where**: gyro vs valve torques" in page and "accelerometer and gyro against the valve model" in page


def test_one_effect_stays_one():
    r = _answer(77, {"accel_bias": [8e-4, -6e-4, 4e-4]})
    assert [m["effect"] for m in r["effects"]] == ["accel_bias"]
    assert r["effect_set"] is None or not r["effect_set"]["explains_heldout"]


def test_in_library_member_named_beside_an_out_of_library_remainder():
    """A gyro bias with LED occlusion (no candidate models it): the bias is
    named with its share, the rest stays a located remainder; the occlusion
    alone stays unexplained (no member earns its place on held-out data).
    Sizes: twice each effect's minimum detectable size in this run (the
    mixture campaign's seed 2050, run 8)."""
    from bench.gap.answers import answer_lines

    bias = [0.0007124016836770431, 0.002469201257574553, 0.0016032926799609988]
    occlusion = [0.09241244798485126, 0.4841359245542046]
    r = _answer(895331565, {"gyro_bias": bias, "led_occlusion": occlusion})
    assert r["verdict"] == "partly_explained"
    assert [m["effect"] for m in r["effects"]] == ["gyro_bias"]
    es = r["effect_set"]
    assert es["partly_explains"] and not es["explains_heldout"]
    assert es["members"][0]["adds_dll_heldout"] > 3.0
    assert es["remainder_where"]["stream"].startswith("pose")  # occlusion biases the measured position
    fitted = np.array([v["value"] for v in r["effects"][0]["parameters"].values()])
    sig = np.array([v["sigma"] for v in r["effects"][0]["parameters"].values()])
    assert np.all(np.abs(fitted - bias) < 4 * sig + 2e-4)
    text = "\n".join(t for _, t in answer_lines(r))
    assert "gyro_bias (partly explained" in text and "remainder:" in text

    alone = _answer(895331565, {"led_occlusion": occlusion})
    assert alone["gap_detected"] and alone["verdict"] == "unexplained" and alone["effects"] == []


def test_thrust_loss_named_beside_a_flexible_panel():
    """A thrust loss on one valve and a flexible panel (no candidate models
    it) on a docking-then-characterisation log: the loss is named, fitted on
    its valve, and the panel's part stays a located remainder."""
    from bench.sim.plans import then_scripts

    then = then_scripts({"manoeuvres": "docking+characterisation"})
    log, _ = reality.simulate_log_with_key(
        11,
        {"thrust_loss": [0, 0, 0, 0.05, 0, 0, 0, 0], "flex_mode": [0.3, 0.012]},
        duration_s=120.0,
        with_truth=False,
        then_scripts=then,
    )
    r = public(diagnose(blind(log), calibration=nullmod.load(manoeuvres="docking+characterisation")))
    assert r["verdict"] == "partly_explained"
    assert [m["effect"] for m in r["effects"]] == ["thrust_loss"]
    loss = {k: v for k, v in r["effects"][0]["parameters"].items()}
    assert abs(loss["loss_3 [1]"]["value"] - 0.05) < 4 * loss["loss_3 [1]"]["sigma"] + 0.005
    assert r["effect_set"]["remainder_where"] is not None


def test_propellant_slosh_is_not_half_named_as_propellant_use():
    """Propellant slosh alone on a docking-then-characterisation log: the
    mass-flow candidate, bounded by what the valves can physically expel,
    cannot take the slosh's part, so nothing is named (the mixture campaign's
    seed 2051, run 3, without its accelerometer bias). Unbounded, it fitted
    0.02 kg/s per open valve, 200 times the 20 mN valve's flow at 20 s of
    specific impulse, and the answer was "partly explained: mass_depletion"."""
    from bench.gap.candidates import candidates_for
    from bench.sim.log_description import resolve
    from bench.sim.plans import then_scripts

    assert candidates_for(8, 0.35, resolve(None).max_mass_flow_kgps)["mass_depletion"].bound == pytest.approx(
        0.02 / (9.80665 * 20.0)
    )
    then = then_scripts({"manoeuvres": "docking+characterisation"})
    log, _ = reality.simulate_log_with_key(
        121894550, {"fuel_slosh": [1.1308307975932066]}, duration_s=120.0, with_truth=False, then_scripts=then
    )
    r = public(diagnose(blind(log), calibration=nullmod.load(manoeuvres="docking+characterisation")))
    assert r["gap_detected"] and r["verdict"] == "unexplained" and r["effects"] == []


def test_set_separability_tells_a_separable_pair_from_a_look_alike():
    """Two effects whose signatures differ are separable from every set one
    step away; replacing the tilt by a thrust loss reproduces a docking
    log's tilt, so that pair is not (docs/GAP.md)."""
    from bench.campaigns.gap.separability import set_separability

    sep = set_separability(
        7,
        {"thrust_loss": [0.0, 0, 0, 0.06, 0, 0, 0.05, 0], "gyro_bias": [2e-3, -1.5e-3, 1e-3]},
        ["gyro_bias", "thrust_loss"],
        120.0,
    )
    assert sep["separable"] and sep["delta2_min"] > 10.8
    assert set(sep["delta2"]) >= {"without gyro_bias", "without thrust_loss", "thrust_loss -> thruster_misalignment"}
    # an in-library set leaves (nearly) nothing beyond the library
    assert sep["beyond_library_delta2"] < 0.1 * sep["lambda"]
    rng = np.random.default_rng(3)
    tilt = (0.004 * rng.normal(size=24)).tolist()
    sep2 = set_separability(
        7,
        {"thruster_misalignment": tilt, "gyro_bias": [2e-3, -1.5e-3, 1e-3]},
        ["gyro_bias", "thruster_misalignment"],
        120.0,
    )
    assert not sep2["separable"]
    assert sep2["closest"].startswith("thruster_misalignment -> ")


def test_mixture_scores_split_by_separability_and_kind():
    from bench.campaigns.gap.validate_mixtures import score_mixtures, summary_lines

    def key(run, kind, scale, members):
        return {"run": run, "kind": kind, "scale": scale, "members": members, "detectable": True}

    def ans(run, named, verdict, sep=True, lib=True, shrink=None, alternatives=()):
        return {
            "run": run,
            "named": named,
            "verdict": verdict,
            "gap_detected": True,
            "t_diagnose_s": 1.0,
            "alternatives": [list(a) for a in alternatives],
            "true_set_shrink": shrink,
            "true_set_measurable": shrink is not None,
            "separability": {"separable": sep, "beyond_library_separable": lib},
        }

    keys = [
        key(0, "pair", 2.0, ["thrust_loss", "gyro_bias"]),
        key(1, "pair", 2.0, ["thruster_misalignment", "gyro_bias"]),
        key(2, "in+out", 2.0, ["accel_bias", "fuel_slosh"]),
        key(3, "in+out", 2.0, ["accel_bias", "led_occlusion"]),
    ]
    answers = [
        ans(0, ["gyro_bias", "thrust_loss"], "explained", shrink=0.9),
        ans(
            1,
            ["thrust_loss", "gyro_bias"],
            "ambiguous",
            sep=False,
            shrink=0.7,
            alternatives=[["gyro_bias", "thruster_misalignment"]],
        ),
        ans(2, ["accel_bias"], "partly_explained", shrink=0.1),
        ans(3, ["accel_bias", "gyro_scale"], "explained", lib=False, shrink=0.2),
    ]
    res = score_mixtures(keys, answers)
    at2 = res["at_2x"]
    assert at2["n"] == 4 and at2["exact_set"] == 0.5 and at2["named_are_real"] == 0.5
    assert at2["exact_set_among_named"] == 0.75  # run 1's set is the alternative its ambiguous answer names
    assert at2["out_of_library_left_unexplained"] == 0.5
    # runs 1 (a look-alike set) and 3 (an out-of-library part the library reproduces) are scored apart
    assert at2["separable"]["n"] == 2 and at2["separable"]["exact_set"] == 1.0
    assert at2["separable"]["out_of_library_left_unexplained"] == 1.0
    assert res["true_set_shrink"]["in-library sets 2x"] == {"median": 0.8, "n": 2}
    assert res["true_set_shrink"]["in + out 2x"]["n"] == 2
    assert any(line.startswith("at 2x, all kinds: exact set 50 %") for line in summary_lines(res))


def test_a_drifting_clock_beside_a_flexible_panel_is_one_clock_not_scale_and_loss():
    """A flight clock fast by 0.005 (twice its minimum detectable size in a
    docking-then-characterisation log) with a flexible panel (out of the
    library): the drift is named as the one-parameter clock, not as a gyro
    scale factor with a thrust loss, and the panel stays a remainder."""
    from bench.sim.plans import then_scripts

    key = {"manoeuvres": "docking+characterisation"}
    log, _ = reality.simulate_log_with_key(
        11,
        {"clock_drift": [0.005], "flex_mode": [0.3, 0.012]},
        duration_s=120.0,
        with_truth=False,
        then_scripts=then_scripts(key),
    )
    r = public(diagnose(blind(log), calibration=nullmod.load(manoeuvres=key["manoeuvres"])))
    named = [m["effect"] for m in r["effects"]]
    assert named == ["clock_drift"] and not {"gyro_scale", "thrust_loss"} & set(named)
    assert r["verdict"] == "partly_explained" and r["effect_set"]["remainder_where"]
    assert r["effects"][0]["adds_dll_heldout"] > 3.0


def test_a_nozzle_tilt_hidden_in_a_thrust_loss_is_listed():
    """A docking approach fires its valves in the same few combinations, so
    a thrust loss of the same valves absorbs a nozzle tilt beside it: the
    answer names the loss, says "ambiguous" and lists the pair, the true set
    (a draw of the seed-2060 mixture campaign at 2x, which was answered
    "explained: thrust_loss" before the hidden members were looked for)."""
    tilt = [-3.2e-3, 1.0e-3, 1.0e-3, 2.3e-3, 2.3e-3, -1.2e-3, 3.4e-3, 5.4e-4, -5.4e-4, 2.3e-3, -2.3e-3, -1.1e-3]
    tilt += [3.0e-3, 1.2e-3, 1.2e-3, -2.2e-3, -2.2e-3, 1.4e-3, 9.8e-4, -2.3e-3, 2.3e-3, -2.0e-4, 2.0e-4, -3.4e-3]
    loss = [0.0133, 0.0135, 0.0101, 0.0126, 0.0078, 0.0068, 0.0189, 0.0171]
    r = _answer(334019379, {"thruster_misalignment": tilt, "thrust_loss": loss})
    assert r["verdict"] == "ambiguous" and r["attribution"][0]["effect"] == "thrust_loss"
    assert ["thrust_loss", "thruster_misalignment"] in [sorted(a["set"]) for a in r["ambiguous_with"]]
