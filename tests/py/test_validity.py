"""A log outside what the diagnosis models well enough: when even its own
null flights (nothing unmodelled) give a statistic that is not finite, the
refusal names the described fields outside the validated envelope instead
of "a tail needs at least 2 finite null values"."""

from __future__ import annotations

import copy

import pytest

from bench.gap import bundled, log_null
from bench.gap.validity import outside_envelope
from bench.runner import cluster
from bench.sim.flight_log import read_flight_log
from bench.sim.log_description import bench_description, resolve
from bench.sim.vehicles import inspector_12kg

WHOLE_RUN = {"t_start_s": 0.0, "t_end_s": 120.05, "manoeuvre": "docking", "starts_at_rest": True}


def test_the_bench_inspectors_are_inside_the_envelope():
    assert outside_envelope(resolve(bench_description())) == []
    assert outside_envelope(resolve(inspector_12kg())) == []


def test_each_field_outside_the_envelope_is_named():
    d = bench_description()
    d["imu"]["gyro_sigma_rps"] = 1e-6
    d["vehicle"]["mass_kg"] = 0.05
    named = outside_envelope(resolve(d))
    assert [n.split(" ")[0] for n in named] == ["imu.gyro_sigma_rps", "vehicle.mass_kg:"]


def _not_finite(seed, flight):
    return {"seed": int(seed), "map_max_abs_z": 500.0, "screen_logp": float("inf")}


def test_a_calibration_whose_null_flights_are_not_finite_names_the_fields(tmp_path, monkeypatch):
    monkeypatch.setattr(cluster, "inside_worker", lambda: True)  # the runs in this process, with null_run replaced
    monkeypatch.setattr(log_null, "null_run", _not_finite)
    log = read_flight_log(bundled.LOG)
    log.description = copy.deepcopy(dict(bench_description(), segments=[WHOLE_RUN]))
    log.description["imu"]["gyro_sigma_rps"] = 1e-6
    with pytest.raises(ValueError) as e:
        log_null.calibrate_for_log(log, runs=3, seed=1, cache_dir=tmp_path, progress=False)
    assert str(e.value).startswith("/description_json: imu.gyro_sigma_rps 1e-06 (validated: >= 0.00063)")
    assert "screen_logp not finite on 3 simulated flights" in str(e.value)


def _raises(seed, flight):
    raise OverflowError("int too large to convert to float")


def test_failed_null_flights_name_the_fields_outside_the_envelope(tmp_path, monkeypatch):
    monkeypatch.setattr(cluster, "inside_worker", lambda: True)
    monkeypatch.setattr(log_null, "null_run", _raises)
    log = read_flight_log(bundled.LOG)
    log.description = copy.deepcopy(dict(bench_description(), segments=[WHOLE_RUN]))
    log.description["vehicle"]["mass_kg"] = 0.1  # 0.16 N of thrust: 1.6 m/s^2
    with pytest.raises(ValueError) as e:
        log_null.calibrate_for_log(log, runs=3, seed=1, cache_dir=tmp_path, progress=False)
    assert str(e.value).startswith("/description_json: vehicle.mass_kg: thrust over mass 1.6 m/s^2")
    assert "3 of 3 null runs for the log failed" in str(e.value) and "OverflowError" in str(e.value)
