"""Relative pose from image features, after the dual-quaternion paper on
kinematically coupled relative dynamics and feature-based (points, lines,
circles) pose estimation: the paper's scenario and its
feature comparison, run on the flight EKF and UKF through the bindings.

Scenario (the paper's section 5): leader on an orbit with a = 7,200 km, e = 0.02,
its body held aligned with its orbit frame; follower 500 kg, J = diag(522,
420, 600) kg m^2, torque free, camera (f = 0.5 m) 1 m off its centre of mass;
the paper's points D1-D4, lines L1-L4 and circles 1-2 (three imaged points
each); 1 s sampling; the paper's two initial guesses. The paper leaves out the
true initial state; ours is stated in TRUTH0 below.

Truth is independent of the flight code: leader and follower are integrated
in the inertial frame (two-body gravity, Euler's equations, quaternion
kinematics) with scipy's solve_ivp (DOP853), and converted to the leader
frame afterwards; image coordinates are projected here with rotation
matrices (lines through two projected points, circles by Rodrigues).
"""

from __future__ import annotations

import math
import os

import numpy as np
from scipy.integrate import solve_ivp

from bench.so3 import qconj, qexp, qmul, quat_from_rotmat, rotmat

MU = 3.986004418e14
A_M = 7.2e6
ECC = 0.02
FOCAL_M = 0.5
MASS_KG = 500.0  # the paper's follower mass: gravity-only forces, so it cancels
INERTIA = np.array([522.0, 420.0, 600.0])
CAMERA_OFFSET_F_M = np.array([0.3, -0.2, 1.0])  # lens from follower c.m., body frame
FEATURE_ORIGIN_L_M = np.array([0.0, 0.0, 0.8])  # leader feature frame origin from leader c.m.
IMAGE_SIGMA_M = 1e-5  # image-plane noise, 1-sigma (about one 10 um pixel)

POINTS = np.array([[1, 1, 0], [-1, 1, 0], [-1, -1, 0], [1, -1, 0]], float)
LINE_DIR = np.array([[-1, 0, 0], [0, -1, 0], [1, 0, 0], [0, 1, 0]], float)
LINE_MOMENT = np.array([[0, 0, 1]] * 4, float)
_H = math.sqrt(0.5)
CIRCLE_AXIS = np.array([[0, _H, _H], [1, 0, 0]], float)
CIRCLE_MOMENT = np.array([[-3, 1, -1], [0, 1, 0]], float)
CIRCLE_START = np.array([[1, 3, -2], [2, 1, -1]], float)
PHI_TRUE = np.array([0.5, 2.0, 4.0, 1.0, 3.0, 5.0])  # angles of the imaged circle points

N_MEAS = 28
CASES = {  # name: (points, lines, circles)
    "points": (True, False, False),
    "lines": (False, True, False),
    "circles": (False, False, True),
    "all": (True, True, True),
}

# Conditions for "converged": pose error below these for the rest of the run.
CONV_POS_M = 0.1
CONV_ATT_DEG = 0.1


# --------------------------------------------------------------------------- quaternions (bench/so3.py)
def qrot(q):
    """Rotation matrix of q (normalised first; rotates child vectors into the parent frame)."""
    return rotmat(np.asarray(q, float) / np.linalg.norm(q))


def qangle(a, b):
    d = abs(float(np.dot(a, b)) / (np.linalg.norm(a) * np.linalg.norm(b)))
    return 2.0 * math.acos(min(1.0, d))


# --------------------------------------------------------------------------- scenario
def leader_nu_dot(nu):
    p = A_M * (1 - ECC**2)
    return math.sqrt(MU / p**3) * (1 + ECC * math.cos(nu)) ** 2


def truth0():
    """True initial relative state: the lP origin at [-20, 35, 60] m in the
    camera, attitude 5.5 deg from the paper's first guess, slow relative rate."""
    q = qexp(np.array([0.03, -0.05, 0.08]))
    R = qrot(q)
    t_c = np.array([-20.0, 35.0, 60.0])
    r = FEATURE_ORIGIN_L_M - R @ (t_c + CAMERA_OFFSET_F_M)
    n = leader_nu_dot(0.0)
    return {
        "q_lf": q,
        "w_fl_f_rps": np.array([2e-4, -1e-4, 3e-4]),
        "r_l_m": r,
        "v_l_mps": np.array([0.01, -2 * n * r[0], 0.02]),
        "phi_rad": PHI_TRUE.copy(),
    }


def guess(which):
    """The paper's initial guesses, its r read as the lP origin in the camera
    frame (the reading that puts the target in front of the lens)."""
    if which == 1:
        q = np.array([1.0, 0.0, 0.0, 0.0])
        t_c = np.array([-30.0, 45.0, 50.0])
    else:
        q = np.array([0.9197, 0.0265, 0.0654, 0.3861])
        q = q / np.linalg.norm(q)
        t_c = np.array([-60.0, 80.0, 100.0])
    r = FEATURE_ORIGIN_L_M - qrot(q) @ (t_c + CAMERA_OFFSET_F_M)
    return {"q_lf": q, "w_fl_f_rps": np.zeros(3), "r_l_m": r, "v_l_mps": np.zeros(3), "phi_rad": PHI_TRUE + 0.3}


def initial_cov(which):
    """P0 over [dtheta, dw, dr, dv, dphi]; wider for the second guess."""
    pos_sig, att_sig = (20.0, 0.2) if which == 1 else (60.0, 0.8)
    d = np.concatenate(
        [np.full(3, att_sig**2), np.full(3, 1e-6), np.full(3, pos_sig**2), np.full(3, 1e-2), np.full(6, 0.25)]
    )
    return np.diag(d)


# --------------------------------------------------------------------------- truth (inertial, solve_ivp)
def _inertial_rhs(_t, y):
    rl, vl, rf, vf = y[0:3], y[3:6], y[6:9], y[9:12]
    q, w = y[12:16], y[16:19]
    al = -MU * rl / np.linalg.norm(rl) ** 3
    af = -MU * rf / np.linalg.norm(rf) ** 3
    wdot = -np.cross(w, INERTIA * w) / INERTIA
    qdot = 0.5 * qmul(q, np.array([0.0, *w]))
    return np.concatenate([vl, al, vf, af, qdot, wdot])


def _leader_frame(rl, vl):
    """C: leader frame L -> inertial (columns x radial, y, z orbit normal); omega_L in L."""
    x = rl / np.linalg.norm(rl)
    h = np.cross(rl, vl)
    z = h / np.linalg.norm(h)
    y = np.cross(z, x)
    nu_dot = np.linalg.norm(h) / np.dot(rl, rl)
    return np.column_stack([x, y, z]), np.array([0.0, 0.0, nu_dot])


def propagate_truth(duration_s, dt_s=1.0, x0=None):
    """Relative truth at t = 0, dt, ..., duration: dict of arrays."""
    x0 = truth0() if x0 is None else x0
    p = A_M * (1 - ECC**2)
    rl0 = np.array([p / (1 + ECC), 0.0, 0.0])  # perigee, nu0 = 0
    vl0 = math.sqrt(MU / p) * np.array([0.0, 1 + ECC, 0.0])
    C0, wL0 = _leader_frame(rl0, vl0)
    r_rel, v_rel = x0["r_l_m"], x0["v_l_mps"]
    rf0 = rl0 + C0 @ r_rel
    vf0 = vl0 + C0 @ (v_rel + np.cross(wL0, r_rel))
    q_il = quat_from_rotmat(C0)
    q_if0 = qmul(q_il, x0["q_lf"])
    w_f0 = x0["w_fl_f_rps"] + qrot(x0["q_lf"]).T @ wL0
    y0 = np.concatenate([rl0, vl0, rf0, vf0, q_if0, w_f0])
    t = np.arange(0.0, duration_s + 0.5 * dt_s, dt_s)
    sol = solve_ivp(_inertial_rhs, (0.0, t[-1]), y0, method="DOP853", t_eval=t, rtol=1e-12, atol=1e-9)
    if not sol.success:
        raise RuntimeError(f"truth integration failed: {sol.message}")
    out = {"t": t, "q_lf": [], "w_fl_f_rps": [], "r_l_m": [], "v_l_mps": []}
    for k in range(len(t)):
        y = sol.y[:, k]
        C, wL = _leader_frame(y[0:3], y[3:6])
        r = C.T @ (y[6:9] - y[0:3])
        v = C.T @ (y[9:12] - y[3:6]) - np.cross(wL, r)
        q_if = y[12:16] / np.linalg.norm(y[12:16])
        q_lf = qmul(qconj(quat_from_rotmat(C)), q_if)
        q_lf = q_lf if q_lf[0] >= 0 else -q_lf
        out["q_lf"].append(q_lf)
        out["r_l_m"].append(r)
        out["v_l_mps"].append(v)
        out["w_fl_f_rps"].append(y[16:19] - qrot(q_lf).T @ wL)
    for k in ("q_lf", "w_fl_f_rps", "r_l_m", "v_l_mps"):
        out[k] = np.array(out[k])
    return out


# --------------------------------------------------------------------------- images (independent projection)
def _camera_point(q_lf, r_l, D):
    R = qrot(q_lf)
    return R.T @ (FEATURE_ORIGIN_L_M + D - r_l) - CAMERA_OFFSET_F_M


def _pinhole(d):
    return FOCAL_M * np.array([d[0] / d[2], d[1] / d[2]])


def image_coordinates(q_lf, r_l):
    """(28,) noiseless image coordinates of every feature, slots as in the flight code."""
    z = np.zeros(N_MEAS)
    for i, D in enumerate(POINTS):
        z[2 * i : 2 * i + 2] = _pinhole(_camera_point(q_lf, r_l, D))
    for i, (l, m) in enumerate(zip(LINE_DIR, LINE_MOMENT)):
        p = np.cross(l, m)  # point of the line nearest the lP origin (m = p x l, |l| = 1)
        a = _pinhole(_camera_point(q_lf, r_l, p - 2 * l))
        b = _pinhole(_camera_point(q_lf, r_l, p + 2 * l))
        u = (b - a) / np.linalg.norm(b - a)
        z[8 + 2 * i : 10 + 2 * i] = a - np.dot(a, u) * u  # foot of the perpendicular from the image origin
    for c in range(2):
        l, m, s0 = CIRCLE_AXIS[c], CIRCLE_MOMENT[c], CIRCLE_START[c]
        p0 = np.cross(l, m)
        for s in range(3):
            phi = PHI_TRUE[3 * c + s]
            v = s0 - p0  # Rodrigues about the axis through p0
            v_rot = v * math.cos(phi) + np.cross(l, v) * math.sin(phi) + l * np.dot(l, v) * (1 - math.cos(phi))
            z[16 + 6 * c + 2 * s : 18 + 6 * c + 2 * s] = _pinhole(_camera_point(q_lf, r_l, p0 + v_rot))
    return z


def measurements(truth, rng):
    clean = np.array([image_coordinates(q, r) for q, r in zip(truth["q_lf"], truth["r_l_m"])])
    return clean + rng.normal(0.0, IMAGE_SIGMA_M, clean.shape)


# --------------------------------------------------------------------------- filters
def make_config():
    import fsw_bindings as fb

    cfg = fb.FeatureFilterConfig()
    cfg.leader_a_m = A_M
    cfg.leader_e = ECC
    cfg.inertia_f_kgm2 = INERTIA
    cfg.focal_m = FOCAL_M
    cfg.camera_offset_f_m = CAMERA_OFFSET_F_M
    cfg.feature_origin_l_m = FEATURE_ORIGIN_L_M
    cfg.image_sigma_m = IMAGE_SIGMA_M
    return cfg


def make_filter(kind, case):
    import fsw_bindings as fb

    use_p, use_l, use_c = CASES[case]
    empty = np.zeros((0, 3))
    cls = fb.FeatureEkf if kind == "ekf" else fb.FeatureUkf
    return cls(
        make_config(),
        POINTS if use_p else empty,
        LINE_DIR if use_l else empty,
        LINE_MOMENT if use_l else empty,
        CIRCLE_AXIS if use_c else empty,
        CIRCLE_MOMENT if use_c else empty,
        CIRCLE_START if use_c else empty,
    )


def run_filter(kind, case, which_guess, truth, z):
    """One run: error histories, pose NEES, failure counts by reason."""
    f = make_filter(kind, case)
    g = guess(which_guess)
    rec = f.init(0.0, 0.0, g["q_lf"], g["w_fl_f_rps"], g["r_l_m"], g["v_l_mps"], g["phi_rad"], initial_cov(which_guess))
    if rec.status != "ok":
        raise ValueError(f"init failed: {rec.status} ({rec.detail})")
    n = len(truth["t"])
    pos_err = np.full(n, np.nan)
    att_err = np.full(n, np.nan)
    nees = np.full(n, np.nan)
    nis = np.full(n, np.nan)
    failures = {}
    for k in range(n):
        if k > 0:
            r = f.predict(float(truth["t"][k]))
            if r.status != "ok":
                key = f"predict_{r.status}_{r.detail}"
                failures[key] = failures.get(key, 0) + 1
            r = f.update(z[k])
            if r.status == "ok":
                nis[k] = r.nis
            else:
                key = f"{r.status}_{r.detail}"
                failures[key] = failures.get(key, 0) + 1
        q_t, r_t = truth["q_lf"][k], truth["r_l_m"][k]
        e_r = r_t - f.r_l_m
        dq = qmul(qconj(f.q_lf), q_t)
        dq = dq if dq[0] >= 0 else -dq
        e_th = 2.0 * dq[1:]  # small-angle body-frame error (as the filter's dtheta)
        pos_err[k] = np.linalg.norm(e_r)
        att_err[k] = math.degrees(qangle(q_t, f.q_lf))
        P = f.P
        idx = np.r_[0:3, 6:9]
        Pp = P[np.ix_(idx, idx)]
        e = np.concatenate([e_th, e_r])
        try:
            nees[k] = float(e @ np.linalg.solve(Pp, e))
        except np.linalg.LinAlgError:
            failures["nees_singular"] = failures.get("nees_singular", 0) + 1
    if not np.isfinite(pos_err[-1]) or pos_err[-1] > 10.0:
        failures["diverged"] = failures.get("diverged", 0) + 1
    return {"pos_err_m": pos_err, "att_err_deg": att_err, "nees": nees, "nis": nis, "failures": failures}


def convergence_time(t, pos_err, att_err):
    """First time after which the pose error stays below CONV_POS_M and CONV_ATT_DEG; None if never."""
    ok = (pos_err < CONV_POS_M) & (att_err < CONV_ATT_DEG)
    if not ok[-1]:
        return None
    bad = np.nonzero(~ok)[0]
    return float(t[0]) if len(bad) == 0 else float(t[bad[-1] + 1])


def summarise(t, runs, n_meas_rows):
    """Steady state = last third of the run; across runs, means (and the worst run)."""
    k0 = int(len(t) * 2 / 3)
    ss_pos = [float(np.sqrt(np.mean(r["pos_err_m"][k0:] ** 2))) for r in runs]
    ss_att = [float(np.sqrt(np.mean(r["att_err_deg"][k0:] ** 2))) for r in runs]
    conv = [convergence_time(t, r["pos_err_m"], r["att_err_deg"]) for r in runs]
    nees_ss = [float(np.nanmean(r["nees"][k0:])) for r in runs]
    nis_ss = [float(np.nanmean(r["nis"][k0:])) if np.any(np.isfinite(r["nis"][k0:])) else None for r in runs]
    failures = {}
    for r in runs:
        for key, v in r["failures"].items():
            failures[key] = failures.get(key, 0) + v
    converged = [c for c in conv if c is not None]
    return {
        "runs": len(runs),
        "steady_pos_err_m": float(np.mean(ss_pos)),
        "steady_pos_err_m_max": float(np.max(ss_pos)),
        "steady_att_err_deg": float(np.mean(ss_att)),
        "steady_att_err_deg_max": float(np.max(ss_att)),
        "convergence_time_s": float(np.mean(converged)) if len(converged) == len(conv) else None,
        "convergence_time_s_per_run": conv,
        "converged_runs": len(converged),
        "nees_pose_mean": float(np.mean(nees_ss)),
        "nees_pose_dof": 6,
        "nis_mean": float(np.mean([v for v in nis_ss if v is not None]))
        if any(v is not None for v in nis_ss)
        else None,
        "nis_dof": n_meas_rows,
        "final_pos_err_m": [float(r["pos_err_m"][-1]) for r in runs],
        "failures_by_reason": failures,
    }


def rows_of(case):
    use_p, use_l, use_c = CASES[case]
    return 8 * use_p + 8 * use_l + 12 * use_c


def comparison(seed, duration_s=300.0, runs=3, ukf=True):
    """The paper's comparison: every case with the EKF from both guesses, and
    the UKF against the EKF on the larger initial error (all features), plus
    the UKF from the first guess. Same truth, the same noise draws per run
    index across cases."""
    truth = propagate_truth(duration_s)
    t = truth["t"]
    zs = [measurements(truth, np.random.default_rng([seed, i])) for i in range(runs)]
    plan = [(case, "ekf", g) for g in (1, 2) for case in CASES]
    if ukf:
        plan += [(case, "ukf", 1) for case in CASES] + [("all", "ukf", 2)]
    cases = {}
    histories = {}
    for case, kind, g in plan:
        name = f"{case}_{kind}_guess{g}"
        rs = [run_filter(kind, case, g, truth, z) for z in zs]
        s = summarise(t, rs, rows_of(case))
        s.update({"features": case, "filter": kind, "initial_guess": g})
        cases[name] = s
        histories[name] = {"pos_err_m": rs[0]["pos_err_m"], "att_err_deg": rs[0]["att_err_deg"]}
    return {
        "seed": seed,
        "duration_s": duration_s,
        "runs": runs,
        "dt_s": 1.0,
        "scenario": {
            "leader_a_m": A_M,
            "leader_e": ECC,
            "focal_m": FOCAL_M,
            "follower_mass_kg": MASS_KG,
            "inertia_kgm2": INERTIA.tolist(),
            "camera_offset_f_m": CAMERA_OFFSET_F_M.tolist(),
            "feature_origin_l_m": FEATURE_ORIGIN_L_M.tolist(),
            "image_sigma_m": IMAGE_SIGMA_M,
            "truth0": {k: np.asarray(v).tolist() for k, v in truth0().items()},
            "convergence": {"pos_m": CONV_POS_M, "att_deg": CONV_ATT_DEG},
        },
        "cases": cases,
        "_histories": histories,
        "_t": t,
    }


def plots(result, folder):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(folder, exist_ok=True)
    t = result["_t"]
    paths = []
    for g in (1, 2):
        fig, ax = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
        for name, h in result["_histories"].items():
            if not name.endswith(f"guess{g}"):
                continue
            ax[0].semilogy(t, np.maximum(h["pos_err_m"], 1e-5), label=name.replace(f"_guess{g}", ""))
            ax[1].semilogy(t, np.maximum(h["att_err_deg"], 1e-5), label=name.replace(f"_guess{g}", ""))
        ax[0].set_ylabel("position error [m]")
        ax[1].set_ylabel("attitude error [deg]")
        ax[1].set_xlabel("time [s]")
        ax[0].set_title(f"feature navigation, initial guess {g} (run 0)")
        ax[0].legend(fontsize=8)
        for a in ax:
            a.grid(True, which="both", alpha=0.3)
        p = os.path.join(folder, f"feature_errors_guess{g}.png")
        fig.tight_layout()
        fig.savefig(p, dpi=110)
        plt.close(fig)
        paths.append(p)
    return paths
