"""The Basilisk engine (bench/sim/basilisk_sim.py) and `proxops simulate`: a
valid format-2 log from either engine; the out-of-library effects only
Basilisk's modules provide (hinged panel, slosh) show in the sensors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench.campaigns import basilisk_crosscheck as xc
from bench.cli import main
from bench.sim import basilisk_sim
from bench.sim.flight_log import read_flight_log, validate_log
from bench.sim.vehicles import VEHICLES


def test_simulate_writes_a_valid_log_from_each_engine(tmp_path):
    logs = {}
    for engine in ("bench", "basilisk"):
        out = tmp_path / f"{engine}.h5"
        key = tmp_path / f"{engine}.json"
        rc = main(
            [
                "simulate",
                "--engine",
                engine,
                "--vehicle",
                "12kg",
                "--effects",
                '{"accel_bias": [1e-3, 0, 0]}',
                "--clocks",
                "as-real-logs",
                "--seed",
                "5",
                "--out",
                str(out),
                "--key",
                str(key),
            ]
        )
        assert rc == 0
        logs[engine] = read_flight_log(out)
        assert validate_log(logs[engine]) == []
        assert json.loads(key.read_text())["effects"] == {"accel_bias": [1e-3, 0.0, 0.0]}
    b, k = logs["bench"], logs["basilisk"]
    assert k.config["engine"] == "basilisk" and k.config["basilisk_version"] == basilisk_sim.basilisk_version()
    assert [s["t_end_s"] for s in b.description["segments"]] == [s["t_end_s"] for s in k.description["segments"]]
    # The same commands and the same drawn stamps, Basilisk's put on its 1 ms grid; the truth of the same flight
    # (at most 0.5 ms apart, at mm/s: micrometres).
    np.testing.assert_array_equal(b.streams["valves"]["on_time_s"], k.streams["valves"]["on_time_s"])
    tb, tk = b.streams["truth"], k.streams["truth"]
    assert tb["t_s"].size == tk["t_s"].size > 2000
    assert np.max(np.abs(tb["t_s"] - tk["t_s"])) <= 0.5e-3 + 1e-9
    assert np.max(np.abs(tb["r_hill_m"] - tk["r_hill_m"])) < 1e-5


def test_unknown_effect_is_refused_with_its_name():
    with pytest.raises(ValueError, match="clock_drift"):
        basilisk_sim.simulate(VEHICLES["12kg"](), xc.short_plan(VEHICLES["12kg"](), 2.0), {"clock_drift": [1e-4]})


@pytest.mark.parametrize(
    "name, params, stream, floor",
    [
        ("flex_mode", [0.5, 0.01], "omega_bi_b_rps", 1e-4),  # the hinged panel swings the body
        ("fuel_slosh", [0.5], "accel_b_mps2", 1e-5),  # the slosh masses take part of the thrust, then give it back
    ],
)
def test_out_of_library_effects_from_basilisk_modules_show_in_the_imu(name, params, stream, floor):
    desc = xc.quiet(VEHICLES["12kg"]())
    plan = xc.short_plan(desc, 8.0)
    with_eff = xc._fly("basilisk", desc, plan, {name: params})
    null = xc._fly("basilisk", desc, plan, {})
    sig = with_eff[stream] - null[stream]
    assert np.sqrt(np.mean(sig**2)) > floor


def test_the_hinged_panel_is_part_of_the_described_vehicle_not_added_to_it():
    # Hub and panel at rest have the described mass, centre of mass and inertia
    # (a panel added on top made the vehicle 12 % heavier about z than described,
    # which the diagnosis rightly took for a thrust loss on the thrusters turning it).
    desc = VEHICLES["12kg"]()
    v = desc["vehicle"]
    for effects in ({"flex_mode": [0.3, 1e-9]}, {"flex_mode": [0.3, 1e-9], "com_offset": [0.004, -0.003, 0.005]}):
        p = basilisk_sim.flown_mass_properties(desc, effects)
        com = np.asarray(v["com_b_m"]) + np.asarray(effects.get("com_offset", np.zeros(3)))
        assert p["mass_kg"] == pytest.approx(v["mass_kg"], abs=1e-12)
        np.testing.assert_allclose(p["com_b_m"], com, atol=1e-9)
        np.testing.assert_allclose(p["inertia_kgm2"], v["inertia_kgm2"], atol=1e-9)


def test_the_hinged_panel_swings_the_hub_at_the_stated_frequency_and_amplitude(monkeypatch):
    from bench.sim.vehicle_sim import Clocks, PlanSegment

    monkeypatch.setattr(basilisk_sim, "PANEL_DAMPING", 0.0)
    f, amp = 0.5, 0.004
    coast = PlanSegment(
        "coast", 12.0, np.array([0.2, -1.5, 0.1]), np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(0), np.zeros((0, 12))
    )
    log, _ = basilisk_sim.simulate(
        xc.quiet(VEHICLES["12kg"]()), [coast], {"flex_mode": [f, amp]}, clocks=Clocks(), noise=False
    )
    t, w = log.streams["truth"]["t_s"], log.streams["truth"]["omega_bi_b_rps"][:, 2]
    fits = []
    for ff in np.linspace(0.9 * f, 1.1 * f, 401):
        a = np.column_stack([np.sin(2 * np.pi * ff * t), np.cos(2 * np.pi * ff * t), np.ones_like(t)])
        c = np.linalg.lstsq(a, w, rcond=None)[0]
        fits.append((np.sum((a @ c - w) ** 2), ff, np.hypot(c[0], c[1]) / (2 * np.pi * ff)))
    _, f_fit, amp_fit = min(fits)
    assert f_fit == pytest.approx(f, rel=1e-3)  # the observed (coupled) frequency, as the bench's mode
    assert amp_fit == pytest.approx(amp, rel=0.01)


def test_a_panel_the_vehicle_cannot_hold_is_refused():
    with pytest.raises(ValueError, match="cannot hold the panel"):
        basilisk_sim.panel_layout(12.0, np.zeros(3), np.diag([0.2, 0.2, 0.004]), 12.0, 0.3, 1e-3)
