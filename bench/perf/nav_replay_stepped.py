"""The gap diagnosis's navigation replay stepped from Python, one IMU sample
and one pose at a time through fsw_bindings.NavUkf: how
bench.gap.replay.replay ran before the whole log went to the flight code in
one call (fsw_bindings.nav_replay, fsw/include/fsw/app/nav_replay.hpp).
Kept as the reference the one-call replay is checked against, bit for bit
(tests/py/test_nav_replay.py), and timed beside (bench/perf/perf_gap.py).
"""

from __future__ import annotations

import numpy as np

from bench.gap.replay import ReplayResult, replay_inputs


def stepped(d, c=None, record_states: bool = False, gate_chi2: float = 0.0) -> ReplayResult:
    """``replay(d, c, record_states, gate_chi2)`` with the filter stepped from
    Python on the same inputs (bench.gap.replay.replay_inputs)."""
    import fsw_bindings as fb

    d, x = replay_inputs(d, c, gate_chi2)
    t, acc, gyr, pr, pq, R = x.imu_t, x.accel, x.gyro, x.pose_r, x.pose_q, x.pose_R
    tc, tf, start, v0sig, t_init = x.pose_tc, x.pose_tf, x.pose_start, x.pose_v0_sigma, x.t_init
    ukf = fb.NavUkf(x.cfg)
    P0 = np.zeros((9, 9))
    P0[0:3, 0:3], P0[6:9, 6:9] = R[0, 0:3, 0:3], R[0, 3:6, 3:6]
    P0[3:6, 3:6] = v0sig[0] ** 2 * np.eye(3)
    ukf.init(t_init, pr[0], np.zeros(3), pq[0], P0)
    m = tc.size
    innov, S, nis, ll, ok = np.zeros((m, 6)), np.zeros((m, 6, 6)), np.zeros(m), np.zeros(m), np.zeros(m, bool)
    states = np.zeros((t.size, 10)) if record_states else None
    eps = 1e-9
    j = 1
    while j < m and tc[j] <= t_init + 1e-9:
        j += 1
    predict, update = ukf.predict, ukf.update_pose
    k0 = int(np.searchsorted(t, t_init + eps, side="right"))
    for k in range(k0, t.size):
        tk = t[k]
        if j < m and start[j] and tc[j] <= tk + eps:
            # A new approach (the flight filter was reset): start again from its first pose.
            P0[0:3, 0:3], P0[6:9, 6:9] = R[j, 0:3, 0:3], R[j, 3:6, 3:6]
            P0[3:6, 3:6] = v0sig[j] ** 2 * np.eye(3)
            ukf = fb.NavUkf(x.cfg)
            ukf.init(tc[j], pr[j], np.zeros(3), pq[j], P0)
            predict, update = ukf.predict, ukf.update_pose
            j += 1
            if tk > tc[j - 1] + eps:
                predict(tk, acc[k], gyr[k])
        else:
            predict(tk, acc[k], gyr[k])
        if record_states:
            states[k] = ukf.state()
        while j < m and tf[j] <= tk + eps and not start[j]:
            rec = update(tc[j], pr[j], pq[j], R[j])
            if rec.status == "ok":
                ok[j] = True
                innov[j], S[j], nis[j], ll[j] = rec.innovation, rec.innovation_cov, rec.nis, rec.log_likelihood
            j += 1
    sel = np.flatnonzero(ok)
    return ReplayResult(d.pose_tc[sel], sel, innov[sel], S[sel], nis[sel], ll[sel], ok[sel], states)
