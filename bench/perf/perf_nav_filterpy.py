"""Side-by-side timing, in one process, of the flight navigation UKF through
the bindings (double, and the float build) and FilterPy's
UnscentedKalmanFilter on the same 9-state problem.

Both filters: state [r_hill (3), v_hill (3), attitude (3)], CW closed-form
step with the exact constant-acceleration term (Phi, Gamma from the
bindings), accelerometer sample rotated into Hill with the attitude, attitude
propagated with the Hill frame turning at n, the same process noise Q and
pose noise R, scaled sigma points alpha = 1, beta = 2, kappa = 0. FilterPy
carries the attitude as an absolute rotation vector (its sigma points and
means are plain vector arithmetic); ours is the multiplicative quaternion
filter. Medians of per-call wall times (time.perf_counter_ns): first
with the two filters called in turn on each sample (each call finds the
caches holding the other's work), then each of ours stepped alone over the
same samples (what a log stepped from Python sees).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python -m bench.perf.perf_nav_filterpy [--predicts 3000] [--json OUT]

PROXOPS_BINDINGS_DIR=<cmake build>/python times a freshly built module
instead of the installed one.
"""

from __future__ import annotations

import argparse
import glob
import importlib.util
import os
import platform
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from bench.so3 import qexp, qlog, qmul, rotmat  # noqa: E402


def _load_bindings():
    d = os.environ.get("PROXOPS_BINDINGS_DIR")
    if d:
        found = glob.glob(os.path.join(d, "fsw_bindings*.so"))
        if not found:
            raise RuntimeError(f"PROXOPS_BINDINGS_DIR={d}: no fsw_bindings module there")
        spec = importlib.util.spec_from_file_location("fsw_bindings", found[0])
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        sys.modules["fsw_bindings"] = mod
    import fsw_bindings

    return fsw_bindings


fb = _load_bindings()

DT = 0.1
POS_SIGMA = 0.0375
ATT_SIGMA = 0.01


def make_filterpy(n, Q, R, x0, P0):
    from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

    phi = fb.cw_stm(n, DT)
    gam = fb.cw_accel_response(n, DT)
    hill = qexp(np.array([0.0, 0.0, -n * DT]))

    def fx(x, dt, accel=np.zeros(3), omega=np.zeros(3)):
        q = qexp(x[6:9])
        a_mid = accel + 0.5 * dt * np.cross(omega, accel)
        a_h = rotmat(q) @ a_mid
        th = 0.5 * n * dt
        a_h = np.array([a_h[0] + th * a_h[1], a_h[1] - th * a_h[0], a_h[2]])
        out = np.empty(9)
        out[:6] = phi @ x[:6] + gam @ a_h
        out[6:] = qlog(qmul(qmul(hill, q), qexp(omega * dt)))
        return out

    def hx(x):
        return np.concatenate([x[:3], x[6:9]])

    pts = MerweScaledSigmaPoints(9, alpha=1.0, beta=2.0, kappa=0.0)
    ukf = UnscentedKalmanFilter(dim_x=9, dim_z=6, dt=DT, fx=fx, hx=hx, points=pts)
    ukf.x = x0.copy()
    ukf.P = P0.copy()
    ukf.Q = Q.copy()
    ukf.R = R.copy()
    return ukf


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip() + f", {os.cpu_count()} CPUs"
    except OSError:
        pass
    return platform.processor()


def _medians_us(times_ns: dict) -> dict:
    return {k: float(np.median(v)) / 1e3 for k, v in times_ns.items() if v}


def _maker(kind, cfg, start):
    """A function that makes a filter of ``kind`` set at ``start`` (r, v, q, P0) at t = 0."""

    def make():
        f = kind(cfg)
        f.init(0.0, *start)
        return f

    return make


def _alone(make, accel, omega, meas_noise, R) -> dict:
    """Per-call times of one of our filters stepped by itself over the same
    samples (no FilterPy call between: the caches hold our code and data,
    as when a whole log is stepped from Python)."""
    f = make()
    clock = time.perf_counter_ns
    t_pred, t_upd = [], []
    for k in range(accel.shape[0]):
        t = (k + 1) * DT
        a, w = accel[k], omega[k]
        t0 = clock()
        f.predict(t, a, w)
        t_pred.append(clock() - t0)
        if (k + 1) % 10 == 0:
            e = meas_noise[(k + 1) // 10]
            r_meas = f.r_hill_m + POS_SIGMA * e[:3]
            q_meas = fb.boxplus(f.q_hb, ATT_SIGMA * e[3:])
            t0 = clock()
            f.update_pose(t, r_meas, q_meas, R)
            t_upd.append(clock() - t0)
    return {"predict": float(np.median(t_pred)) / 1e3, "update": float(np.median(t_upd)) / 1e3}


def _config():
    """The filters' configuration: 500 km orbit, 10 Hz IMU, the bench's noises."""
    cfg = fb.NavConfig()
    cfg.n_radps = fb.orbit_rate(fb.EARTH_RADIUS + 500e3)
    cfg.dt_imu_s = DT
    cfg.accel_sigma_mps2 = 0.25 * 0.020 / 3.0
    cfg.gyro_sigma_rps = 0.005
    return cfg


def run(predicts: int, seed: int) -> dict:
    load_before = os.getloadavg()[0]
    cfg = _config()
    n = cfg.n_radps
    gam = fb.cw_accel_response(n, DT)
    Q = np.zeros((9, 9))
    Q[:6, :6] = cfg.accel_sigma_mps2**2 * gam @ gam.T
    Q[6:, 6:] = (cfg.gyro_sigma_rps * DT) ** 2 * np.eye(3)
    R = np.diag([POS_SIGMA**2] * 3 + [ATT_SIGMA**2] * 3)
    P0 = np.diag([0.05**2] * 3 + [0.01**2] * 3 + [0.05**2] * 3)
    r0 = np.array([0.75, 0.0, 0.0])
    v0 = np.array([0.0, -2.0 * n * 0.75, 0.0])
    phi0 = np.array([0.1, -0.2, 0.3])
    q0 = qexp(phi0)

    ours = fb.NavUkf(cfg)
    ours.init(0.0, r0, v0, q0, P0)
    ours_f = fb.NavUkfFloat(cfg) if hasattr(fb, "NavUkfFloat") else None  # the float build, same calls
    _ = ours_f is not None and ours_f.init(0.0, r0, v0, q0, P0)
    theirs = make_filterpy(n, Q, R, np.concatenate([r0, v0, phi0]), P0)

    rng = np.random.default_rng(seed)
    accel = 2e-3 * rng.standard_normal((predicts, 3))
    omega = np.array([0.01, -0.02, 0.015]) + 0.005 * rng.standard_normal((predicts, 3))
    meas_noise = rng.standard_normal((predicts // 10 + 1, 6))

    t_pred = {"ours": [], "filterpy": [], "ours_float": []}
    t_upd = {"ours": [], "filterpy": [], "ours_float": []}
    clock = time.perf_counter_ns
    max_pos_diff = 0.0
    for k in range(predicts):
        t = (k + 1) * DT
        a, w = accel[k], omega[k]
        t0 = clock()
        ours.predict(t, a, w)
        t1 = clock()
        theirs.predict(accel=a, omega=w)
        t2 = clock()
        t_pred["ours"].append(t1 - t0)
        t_pred["filterpy"].append(t2 - t1)
        if ours_f is not None:
            t0 = clock()
            ours_f.predict(t, a, w)
            t_pred["ours_float"].append(clock() - t0)
        if (k + 1) % 10 == 0:
            e = meas_noise[(k + 1) // 10]
            r_meas = ours.r_hill_m + POS_SIGMA * e[:3]
            q_meas = fb.boxplus(ours.q_hb, ATT_SIGMA * e[3:])
            z = np.concatenate([r_meas, qlog(q_meas)])
            t0 = clock()
            ours.update_pose(t, r_meas, q_meas, R)
            t1 = clock()
            theirs.update(z)
            t2 = clock()
            t_upd["ours"].append(t1 - t0)
            t_upd["filterpy"].append(t2 - t1)
            if ours_f is not None:
                t0 = clock()
                ours_f.update_pose(t, r_meas, q_meas, R)
                t_upd["ours_float"].append(clock() - t0)
            max_pos_diff = max(max_pos_diff, float(np.abs(theirs.x[:3] - ours.r_hill_m).max()))

    kinds = {"ours": fb.NavUkf, **({"ours_float": fb.NavUkfFloat} if ours_f is not None else {})}
    res = {
        "alone_median_us": {
            k: _alone(_maker(f, cfg, (r0, v0, q0, P0)), accel, omega, meas_noise, R) for k, f in kinds.items()
        },
        "predicts": predicts,
        "updates": len(t_upd["ours"]),
        "predict_median_us": _medians_us(t_pred),
        "update_median_us": _medians_us(t_upd),
        "max_pos_estimate_diff_m": max_pos_diff,
        "python": platform.python_version(),
        "machine": _cpu_model(),
        "load_average_1min_before": load_before,
    }
    res["predict_ratio"] = res["predict_median_us"]["filterpy"] / res["predict_median_us"]["ours"]
    res["update_ratio"] = res["update_median_us"]["filterpy"] / res["update_median_us"]["ours"]
    return res


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m bench.perf.perf_nav_filterpy", description=__doc__.splitlines()[0])
    p.add_argument("--predicts", type=int, default=3000, help="IMU predicts (a pose update every 10th)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--json", default=None, help="write the figures here")
    args = p.parse_args(argv)
    res = run(args.predicts, args.seed)
    print(f"{'step':<8} {'ours [us]':>12} {'ours float [us]':>16} {'FilterPy [us]':>14} {'ratio':>8}")
    for step in ("predict", "update"):
        m = res[f"{step}_median_us"]
        fl = f"{m['ours_float']:>16.2f}" if "ours_float" in m else f"{'-':>16}"
        print(f"{step:<8} {m['ours']:>12.2f} {fl} {m['filterpy']:>14.1f} {res[f'{step}_ratio']:>7.0f}x")
    al = res["alone_median_us"]
    print(
        "ours alone (no FilterPy call between, as a log stepped from Python): "
        + "; ".join(f"{k} predict {v['predict']:.2f} us, update {v['update']:.2f} us" for k, v in al.items())
    )
    print(
        f"({res['predicts']} predicts, {res['updates']} updates, medians per call; "
        f"largest position estimate difference {res['max_pos_estimate_diff_m']:.2e} m)"
    )
    if args.json:
        from bench.report import write_json

        write_json(args.json, res)
    return 0


if __name__ == "__main__":
    sys.exit(main())
