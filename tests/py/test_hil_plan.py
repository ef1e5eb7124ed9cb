"""`proxops hil --plan FILE`: a valve plan (the JSON of `proxops plan
--separate --json`) uplinked to fsw_node over the pseudo-terminal link,
checked and run by the flight side, flown on the bench's plant; the
valves the plant fired, and the flight log's valves stream, are the
plan's. A plan the flight side refuses is reported as refused and flies
nothing."""

import json

import numpy as np
import pytest

pytest.importorskip("serial")

from bench import cli  # noqa: E402
from bench.sim.flight_log import read_flight_log  # noqa: E402
from hil_sim.faults import FaultConfig  # noqa: E402
from hil_sim.plan_link import PlanHilConfig, plan_entries, plan_masks, run_plan_hil  # noqa: E402

# Three runs, each from its own start (times from the run's start), as
# proxops plan writes them: valve 0 for 1 s, valves 3 and 5 together, then
# valve 7 for 0.5 s.
PLAN = {
    "designed": {
        "schedule": [
            {"run": 0, "pass": 0, "duration_s": 5.0, "valves": {"0": [[2.0, 3.0]]}, "block": 0},
            {"run": 1, "pass": 0, "duration_s": 4.0, "valves": {"3": [[2.0, 2.5]], "5": [[2.2, 3.0]]}, "block": 1},
            {"run": 2, "pass": 1, "duration_s": 3.5, "valves": {"7": [[2.0, 2.5]]}, "block": 2},
        ]
    }
}


def test_plan_entries_are_the_runs_end_to_end():
    entries, duration = plan_entries(PLAN)
    assert duration == 12.5
    assert entries == [(0, 2.0, 3.0), (3, 7.0, 7.5), (5, 7.2, 8.0), (7, 11.0, 11.5)]
    masks = plan_masks(entries, duration, 0.1)
    assert len(masks) == 125 and masks[20] == 1 and masks[72] == (1 << 3) | (1 << 5) and masks[75] == 1 << 5
    with pytest.raises(ValueError, match="no schedule"):
        plan_entries({"designed": {}})


def test_a_short_plan_flies_over_the_link_as_planned(tmp_path):
    plan_file, out, report = tmp_path / "plan.json", tmp_path / "hil.json", tmp_path / "report"
    plan_file.write_text(json.dumps(PLAN))
    rc = cli.main(["hil", "--plan", str(plan_file), "--seed", "4", "--json", str(out), "--report", str(report)])
    assert rc == 0
    s = json.loads(out.read_text())
    p = s["plan"]
    assert (p["verdict"], p["started"], p["ended"]) == ("accepted", True, "finished")
    assert p["flight_status"]["state"] == "finished" and p["flight_status"]["commands_refused"] == 0
    assert p["intervals"] == 125 and p["intervals_firing"] == 10 + 10 + 5  # valves 3 and 5: 7.0 to 8.0 s
    assert p["intervals_differing"] == 0 and p["firing_outside_the_plan"] == 0
    assert p["valve_seconds_planned"] == pytest.approx(1.0 + 0.5 + 0.8 + 0.5)
    assert p["valve_seconds_flown"] == pytest.approx(p["valve_seconds_planned"])
    assert p["commands_received"] == 125
    assert s["fsw_node_exit_code"] == 0 and s["bad_crc_delivered"] == 0
    # The flight log's valves stream: the plan's masks from the start tick
    # (the start is tagged at the first IMU tick, 0.1 s), closed before and after.
    v = read_flight_log(report / "flight_log.h5").streams["valves"]
    t, mask = np.asarray(v["t_s"]), np.asarray(v["mask"])
    want = plan_masks(*plan_entries(PLAN), 0.1)
    k0 = int(np.argmin(np.abs(t - 0.1)))
    np.testing.assert_array_equal(mask[k0 : k0 + len(want)], want)
    assert not mask[:k0].any() and not mask[k0 + len(want) :].any()
    # Every whole-interval firing of the plan taught the flight learner.
    assert "learner samples 25" in s["fsw_node_summary"]


def test_a_refused_plan_is_reported_refused_and_flies_nothing(tmp_path, capsys):
    bad = {"designed": {"schedule": [{"duration_s": 30.0, "valves": {"2": [[2.0, 27.0]]}}]}}  # 25 s > 20 s
    plan_file, out = tmp_path / "plan.json", tmp_path / "hil.json"
    plan_file.write_text(json.dumps(bad))
    rc = cli.main(["hil", "--plan", str(plan_file), "--json", str(out)])
    assert rc == 1
    assert "on_time_too_long, refused; nothing flown" in capsys.readouterr().out
    p = json.loads(out.read_text())["plan"]
    assert (p["verdict"], p["started"], p["commands_received"]) == ("on_time_too_long", False, 0)
    assert p["flight_status"]["state"] == "empty" and p["flight_status"]["commands_refused"] == 1


def test_plan_flies_over_a_lossy_link_with_entries_sent_again():
    """Bytes lost on the uplink lose plan entries: the load is answered
    incomplete and the entries are sent again until the plan is whole; a
    command lost on the downlink leaves that interval's valves closed."""
    entries, duration = plan_entries(PLAN)
    res = run_plan_hil(
        PlanHilConfig(entries, duration, seed=2, faults=FaultConfig(drop_rate=0.003), step_timeout_s=0.02)
    )
    p = res["plan"]
    assert p["verdict"] == "accepted" and p["started"]
    assert res["bad_crc_delivered"] == 0 and res["fsw_node_exit_code"] == 0
    # What the plant fired never goes beyond the plan: at most a lost command closed a valve.
    assert p["firing_outside_the_plan"] == 0
    assert p["valve_seconds_flown"] <= p["valve_seconds_planned"] + 1e-9
