"""The sets an answer cannot be told from (bench/gap/alternatives.py), on
two draws of the seed-2060 mixture campaign whose data do not separate
their set (docs/results)."""

import numpy as np
import pytest

from bench.campaigns.gap.validate import blind
from bench.gap import null as nullmod
from bench.gap.answers import answer_lines, listed_sets
from bench.gap.diagnose import diagnose, public
from bench.sim import reality

# Run 26 of the seed-2060 mixture campaign: a gyro scale factor, a thrust
# loss on every valve and a nozzle tilt, each at twice its own minimum
# detectable size in a 120 s docking run (the campaign's key, to the bit:
# the answer near a decision boundary moves with the last digits).
GYRO_SCALE = [-0.21095588650395297, 0.035389397322436206, -0.15317996720773652]
LOSS = [0.0175476268335531, 0.007892817821490716, 0.02765731694097275, 0.029702040773774526, 0.029997541868252323]
LOSS += [0.030375673662982026, 0.022287845132236993, 0.014342470932506488]
TILT = [-0.007081186718375611, -0.002312088921977242, -0.002312088921977241, -0.0038575974963470884]
TILT += [-0.003857597496347089, -0.005574280116670876, 0.007679363287087586, 0.0009649080815524035]
TILT += [-0.0009649080815524045, 0.005429742219236648, -0.005429742219236648, -0.001367667566346836]
TILT += [0.005068955789368427, -0.004191682413553491, -0.0041916824135534905, 0.0018918753184912088]
TILT += [0.0018918753184912088, -0.007326413260615764, 0.0026447334994449613, 0.005188453547237004]
TILT += [-0.005188453547237007, -0.004548122769071346, 0.004548122769071346, -0.004411788102534903]
# Run 49: a thrust loss beside a flexible panel (outside the library).
PANEL_LOSS = [0.007857890549556448, 0.0024805801649011978, 0.00673294066698748, 0.0039457929105374675]
PANEL_LOSS += [0.007148082734511788, 0.005570518686430172, 0.007529912910705307, 0.006316102657538818]
PANEL = [0.18554197159193964, 0.005611024611029923]


def _diagnosed(seed, effects):
    log, _ = reality.simulate_log_with_key(seed, effects, duration_s=120.0, with_truth=False)
    return diagnose(blind(log), calibration=nullmod.load())


@pytest.fixture(scope="module")
def three_effects():
    return _diagnosed(39699221, {"gyro_scale": GYRO_SCALE, "thrust_loss": LOSS, "thruster_misalignment": TILT})


def test_a_set_two_steps_from_the_answer_is_listed(three_effects):
    r = public(three_effects)
    named = {m["effect"] for m in r["effects"]}
    truth = {"gyro_scale", "thrust_loss", "thruster_misalignment"}
    # The data do not separate the set: the answer is another one, and says so.
    assert named != truth and r["verdict"] == "ambiguous"
    sets = [set(s) for s in listed_sets(r)]
    assert truth in sets
    # The true set is two steps from the answer (a member swapped and one
    # added): listed as a hidden member beside a set that explains as well
    # as the answer.
    assert len(named ^ truth) == 2
    (entry,) = [a for a in r["ambiguous_with"] if set(a["set"]) == truth]
    assert "add" in entry and set(entry["to"]) < truth
    assert any("logp_beside" in a and set(a["set"]) == set(entry["to"]) for a in r["ambiguous_with"])
    # Each listed set once, never the answer itself, each with what separates it.
    assert len({frozenset(s) for s in sets}) == len(sets) and named not in sets
    assert all(a["separate_by"] for a in r["ambiguous_with"])
    which = dict(answer_lines(r))["which"]
    assert "cannot be told from:" in which


def test_the_reduced_problem_fits_as_the_rows_do(three_effects):
    from bench.gap.alternatives import _reduced, screened
    from bench.gap.attribute import training_residuals
    from bench.gap.select import two_dll

    it = three_effects["_internal"]
    ctx, fits_by = it["ctx"], screened(it["fits"])
    e0, _ = training_residuals(ctx)
    red, z = _reduced(fits_by, e0)
    assert np.isclose(z @ z, e0 @ e0, rtol=1e-10)
    for names in (
        ["thrust_loss"],
        ["gyro_scale", "thruster_misalignment"],
        ["accel_bias", "com_offset", "thrust_loss"],
    ):
        full, rank = two_dll(ctx, fits_by, names, e0)
        reduced, rank_r = two_dll(ctx, red, names, z)
        assert rank_r == rank and reduced == pytest.approx(full, rel=1e-4)


def test_a_partial_answer_lists_itself_without_each_member():
    """A thrust loss beside a flexible panel (outside the library): the
    answer names the loss and a gyro scale for part of the panel; the loss
    alone is listed, the scale possibly the panel's shadow."""
    r = public(_diagnosed(715864630, {"thrust_loss": PANEL_LOSS, "flex_mode": PANEL}))
    assert r["verdict"] == "partly_explained"
    named = [m["effect"] for m in r["effects"]]
    assert len(named) == 2 and "thrust_loss" in named
    drops = {a["drop"]: a["set"] for a in r["ambiguous_with"] if "drop" in a}
    assert drops == {m: [n for n in named if n != m] for m in named}
    assert ["thrust_loss"] in listed_sets(r)


def test_an_unexplained_answer_lists_the_library_part_that_may_sit_beside():
    """A differential drag beside propellant slosh (outside the library), run
    23 of the seed-2061 mixture campaign at 2x: no set passes every
    held-out test, so the answer stays "unexplained"; the drag gains on the
    held-out data and is listed as a possible part, with its look-alikes."""
    r = public(
        _diagnosed(
            981677316,
            {"differential_drag": [43.13898631423505, 12.128188271557383], "fuel_slosh": [1.2979315329401908]},
        )
    )
    assert r["verdict"] == "unexplained" and not r["effects"]
    first = r["ambiguous_with"][0]
    assert first["set"] == ["differential_drag"] and first["part_of_gap"]
    assert ["differential_drag"] in listed_sets(r)
    which = dict(answer_lines(r))["which"]
    assert which.startswith("unexplained: ") and "part of it could be: differential_drag" in which
