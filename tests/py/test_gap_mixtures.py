"""Several effects at once: forward selection names every effect the data
support, refitted jointly, each member with its share; one effect alone
stays one."""
import numpy as np
import pytest

from bench.gap import null as nullmod
from bench.gap.diagnose import diagnose, public
from bench.gap.validate import blind

reality = pytest.importorskip("bench.reality")


def _answer(seed, effects):
    log, _ = reality.simulate_log_with_key(seed, effects, duration_s=120.0, with_truth=False)
    return public(diagnose(blind(log), calibration=nullmod.load()))


def test_thrust_loss_and_gyro_bias_are_both_named():
    r = _answer(7, {"thrust_loss": [0.0, 0, 0, 0.06, 0, 0, 0.05, 0], "gyro_bias": [2e-3, -1.5e-3, 1e-3]})
    assert r["verdict"] == "explained"
    assert sorted(m["effect"] for m in r["effects"]) == ["gyro_bias", "thrust_loss"]
    es = r["effect_set"]
    assert es["explains_heldout"] and es["every_member_needed"] and es["shrink_heldout"]["fraction"] > 0.8
    gb = next(m for m in r["effects"] if m["effect"] == "gyro_bias")["parameters"]
    fitted = np.array([v["value"] for v in gb.values()])
    sig = np.array([v["sigma"] for v in gb.values()])
    assert np.all(np.abs(fitted - [2e-3, -1.5e-3, 1e-3]) < 4 * sig + 1e-4)
    # each member adds to the held-out likelihood beside the other
    assert all(m["adds_dll_heldout"] > 3.0 for m in r["effects"])


def test_one_effect_stays_one():
    r = _answer(77, {"accel_bias": [8e-4, -6e-4, 4e-4]})
    assert [m["effect"] for m in r["effects"]] == ["accel_bias"]
    assert r["effect_set"] is None or not r["effect_set"]["explains_heldout"]
