"""The HIL recorder writes the valve commands the plant flew as the flight
log's `valves` stream (docs/FLIGHT_LOG.md), so `proxops diagnose` on a HIL
log examines the dynamics channel instead of saying it could not."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench import cli
from bench.sim.flight_log import read_flight_log
from bench.sim.scenario_docking import ScenarioConfig, run_docking
from hil_sim.report import write_hil_report

DYNAMICS = ("accelerometer vs valves", "gyro vs valve torques")


def test_the_recorded_log_holds_every_steps_valve_command(tmp_path):
    # Two chained runs, as a HIL run longer than one docking records them.
    runs = [run_docking(3, ScenarioConfig(t_max_s=20.0)), run_docking(4, ScenarioConfig(t_max_s=10.0))]
    summary = {"scenario": "docking", "seed": 3, "faults": {}}
    assert write_hil_report({"runs": runs, "steps": 0}, summary, tmp_path) is None
    log = read_flight_log(tmp_path / "flight_log.h5")
    v = log["valves"]
    np.testing.assert_array_equal(v["mask"], np.concatenate([r.config for r in runs]))
    assert np.any(v["mask"] != 0)  # the controller fired: the stream is not a row of zeros
    n0 = runs[0].config.size
    np.testing.assert_allclose(v["t_s"][:n0], runs[0].t[:n0])
    # The second run's commands on the time line its IMU samples run on.
    i0 = int(np.searchsorted(log["imu"]["t_s"], v["t_s"][n0]))
    assert v["t_s"][n0] == pytest.approx(log["imu"]["t_s"][i0] - 0.1)
    np.testing.assert_allclose(v["interval_s"], 0.1)


def test_diagnose_on_a_hil_log_examines_the_dynamics_channel(tmp_path, capsys):
    pytest.importorskip("serial")
    report, out = tmp_path / "report", tmp_path / "diagnosis.json"
    rc = cli.main(["hil", "--duration", "12", "--json", str(tmp_path / "hil.json"), "--report", str(report)])
    assert rc == 0, capsys.readouterr().err[-2000:]
    assert "valves" in read_flight_log(report / "flight_log.h5").streams
    assert cli.main(["diagnose", str(report / "flight_log.h5"), "--json", str(out), "--quiet"]) == 0
    channels = json.loads(out.read_text())["examined"]["channels"]
    for name in DYNAMICS:
        assert channels[name]["examined"] and channels[name]["rows"] > 0, channels
