"""The HIL loop: the flight executable behind a pseudo-terminal gives the
same estimates as the filter in-process, and survives a faulty link."""

import fsw_bindings as fb
import numpy as np
import pytest

pytest.importorskip("serial")
if not hasattr(fb, "NavUkf"):
    pytest.skip("fsw_bindings without NavUkf", allow_module_level=True)

from bench.sim.scenario_docking import ScenarioConfig, nav_config, run_docking  # noqa: E402
from hil_sim.faults import FaultConfig  # noqa: E402
from hil_sim.link_nav import LinkNav  # noqa: E402
from hil_sim.pty_link import PtyLink  # noqa: E402
from hil_sim.run import HilConfig, nav_errors, run_hil  # noqa: E402


def test_link_estimates_equal_in_process_estimates():
    cfg = ScenarioConfig(t_max_s=20.0)
    ref = run_docking(5, cfg)
    with PtyLink() as link:
        nav = LinkNav(link, step_timeout_s=2.0)
        nav.configure_nav(nav_config(cfg))
        hil = run_docking(5, cfg, nav=nav)
    assert ref.est.shape == hil.est.shape
    # The pose sigma crosses the link as sqrt(R) and is squared again on the
    # flight side: that round trip may move R by one ulp, nothing else differs.
    np.testing.assert_allclose(hil.est, ref.est, rtol=0, atol=1e-12)
    np.testing.assert_allclose(hil.updates.nis, ref.updates.nis, rtol=1e-9)
    assert list(hil.updates.status) == list(ref.updates.status)
    # P over the link is the diagonal of the flight covariance.
    np.testing.assert_allclose(
        np.diagonal(hil.P, axis1=1, axis2=2), np.diagonal(ref.P, axis1=1, axis2=2), rtol=1e-12, atol=0
    )


def test_faulty_link_rejects_every_corrupted_packet_and_keeps_navigating():
    clean = run_hil(HilConfig(duration_s=40.0, seed=3))
    assert clean["bad_crc_delivered"] == 0 and sum(clean["flight_rejected_by_reason"].values()) == 0
    faults = FaultConfig(ber=1e-4, drop_rate=0.01)
    res = run_hil(HilConfig(duration_s=40.0, seed=3, faults=faults, step_timeout_s=0.02))
    assert res["fsw_node_exit_code"] == 0
    assert res["bad_crc_delivered"] == 0
    assert sum(res["flight_rejected_by_reason"].values()) > 0
    assert sum(res["bench_rejected_by_reason"].values()) > 0
    assert res["faults_up"]["frames_touched"] > 0
    # Bound: twice the clean-link navigation bound of the docking scenario
    # (0.10 m per axis, docs/perf/nav_campaign.md). A 1 % byte loss loses about half of the
    # 60-to-90-byte frames, so whole IMU steps and poses go missing.
    e_clean = max(nav_errors(clean["runs"])["max_pos_err_m"])
    e_fault = max(nav_errors(res["runs"])["max_pos_err_m"])
    assert e_clean <= 0.10
    assert e_fault <= 2 * 0.10, (e_clean, e_fault)


def test_garbage_on_the_link_is_counted_not_fatal():
    with PtyLink() as link:
        nav = LinkNav(link, step_timeout_s=2.0)
        P0 = np.diag([0.0025] * 3 + [1e-4] * 3 + [0.0025] * 3)
        assert nav.init(0.0, np.array([0.0, -0.7, 0.0]), np.zeros(3), np.array([1.0, 0, 0, 0]), P0).status == "ok"
        rng = np.random.default_rng(0)
        link.write(bytes(rng.integers(0, 256, 5000, dtype=np.uint8)) + b"\x00")
        for k in range(1, 12):
            rec = nav.predict(0.1 * k, np.zeros(3), np.zeros(3))
            assert rec.received and rec.status == "ok"
        assert link.node_alive()
        assert sum(nav.rejected_by_reason().values()) >= 1
    assert link.proc.returncode == 0


def test_fsw_node_stops_cleanly_on_sigterm():
    link = PtyLink()
    assert link.node_alive()
    ended = link.close()
    assert ended["exit_code"] == 0
    assert "stopped" in ended["stderr"]


def test_flight_learner_hears_the_valve_commands_and_reports_over_the_link():
    res = run_hil(HilConfig(duration_s=30.0, seed=5, learner=True))
    outs = res["learner_outputs"]
    assert len(outs) > 30  # one tm_learner per firing interval
    n_samples = [v[0] for _, v in outs]
    assert n_samples[-1] == 30  # the window (30) has filled
    assert all(np.all(np.isfinite(v[2:])) for _, v in outs)
    times = [t for t, _ in outs]
    assert all(b > a for a, b in zip(times, times[1:]))


def test_a_run_cut_by_the_end_of_the_hil_run_is_reported_as_such(capsys):
    import argparse

    from bench.commands.hil import hil_summary, print_summary

    res = run_hil(HilConfig(duration_s=5.0, seed=2))
    (run,) = res["runs"]
    assert not run.summary.docked and run.summary.cut_by_duration
    args = argparse.Namespace(
        scenario="docking",
        duration=5.0,
        realtime=False,
        ber=0.0,
        drop_rate=0.0,
        burst_rate=0.0,
        duplicate_rate=0.0,
        reorder_rate=0.0,
        stall_rate=0.0,
        seed=2,
    )
    s = hil_summary(res, args)
    assert s["docking_runs_cut_by_duration"] == 1
    print_summary(s)
    assert "1 docking run(s), 0 docked, 1 cut short by the end of the 5 s" in capsys.readouterr().out
