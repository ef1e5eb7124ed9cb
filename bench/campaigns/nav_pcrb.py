"""The posterior Cramer-Rao bound of the docking scenario's navigation, and
the errors of four filters against it on the same runs (docs/perf/nav.md).

Bound: the recursion of "Posterior Cramer-Rao bounds for discrete-time
nonlinear filtering" (Tichavsky, Muravchik and Nehorai), with its
expectations taken by Monte Carlo over the campaign's own truth trajectories.
The model is the one the flight filter is built on, with the simulated
sensors' noises:

  x = [r_hill (3), v_hill (3), dtheta (3, body-frame attitude error)]
  [r; v]_{k+1} = Phi [r; v]_k + Gamma a_hill(q_k, a_k) + Gamma w_a   (CW, exact for a held input)
  q_{k+1}      = hill_step q_k Exp((omega_k + w_g) dt)
  w_a ~ N(0, sigma_a^2 I), w_g ~ N(0, sigma_g^2 I): each IMU sample's noise held over its step
  pose at whole seconds: r + v_r, v_r ~ N(0, (f |r|)^2 I) (f = 5 %, |r| floored at
  the sensor's 5 cm); q (x) Exp(v_q), v_q ~ N(0, sigma_q^2 I)

so F_k = [[Phi, Gamma C_k], [0, A_k]] with C_k = -Rz R(q_k) [a_mid]x (the
attitude error turns the measured specific force) and A_k = R(omega_k dt)^T,
evaluated at the truth (the true specific force of the step's valves and the
true body rate); the process noise is G u with G = blockdiag(Gamma, dt I),
u ~ N(0, Qu), Q = G Qu G^T (rank 6 of 9). The recursion's
J_{k+1} = D22 - D21 (J_k + D11)^-1 D12 with D11 = E[F^T Q^-1 F],
D12 = -E[F]^T Q^-1, D22 = Q^-1 + E[H^T R^-1 H] is written, by the matrix
inversion lemma, as

  J_{k+1} = (Q + E[F] (J_k + M_k)^-1 E[F]^T)^-1 + E[I_z,k+1],
  M_k = E[dF^T Q^+ dF] = E[dB^T Qu^-1 dB],   dF = F - E[F] = G dB

which needs no inverse of the singular Q: the spread of F over the
trajectories lies in the range of G (dB = [dC; dA / dt]). I_z is the pose's
Fisher information, including the term 6 r r^T / |r|^4 that a noise scaled
with the true range carries (1.5 % of the radial information, 6 f^2).

Prior: the filter starts from the pose captured at t = 0 and a zero velocity
with sigma v0 (the true spread of the start velocity); the bound starts from
the same information: that pose's Fisher information and N(0, v0^2 I) on
the velocity; start position and attitude otherwise unknown (the scenario's
start cone and attitude spread are not used by the filter, nor here).
A pose delivered L seconds after capture counts from its delivery: the bound
at t is the recursion with every pose captured by t - L, propagated to t.

Expectations at step k are means over the runs still flying at k (runs end
at contact, 53 to 175 s); the bound per step is compared with the filters'
mean squared errors over the same runs. Beside it, the per-trajectory
bound (the same recursion run on each trajectory alone, then averaged:
mean_i J_i^-1 >= (mean_i J_i)^-1, the larger of the two).

Figure of merit per block (pos, vel, att) over the window W (after
convergence, t >= t_conv, while at least half the runs fly):
  ratio = sqrt( sum_{runs i, k in W} |e_ik,block|^2 / sum_{i, k in W} tr PCRB_k,block )
with a bootstrap interval over the runs (the bound held fixed). 1 is the
bound; 1.10 is 10 % above it.

Filters, all on each run's logged IMU samples and poses (the same noise
draws), each building the pose covariance from its own range estimate as the
flight filter does:
  ukf          the flight filter (double) as the campaign ran it in the loop
  ukf_float    the flight filter built for float (fsw_bindings.NavUkfFloat)
  filterpy_ukf FilterPy's UnscentedKalmanFilter, same model, noises and
               sigma points (alpha 1, beta 2, kappa 0), attitude as an
               absolute rotation vector, no gate
  ekf          a multiplicative extended Kalman filter (numpy), same model,
               noises and chi-square gate
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from bench.sim.scenario_docking import DockingRun, ScenarioConfig, nav_config
from bench.so3 import boxminus, boxplus, qexp, qlog, qmul, rotmat

BLOCKS = ("pos", "vel", "att")
FILTERS = ("ukf", "ukf_float", "filterpy_ukf", "ekf")
T_CONV_S = 20.0
BOOTSTRAP = 400
MIN_RANGE_M = 0.05  # PoseSensor.min_range_m


def skew(a) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


class Model:
    """The filter's discrete model at the scenario's settings (module docstring)."""

    def __init__(self, cfg: ScenarioConfig):
        import fsw_bindings as fb

        nc = nav_config(cfg)
        self.dt = float(nc.dt_imu_s)
        self.n = float(nc.n_radps)
        self.sa, self.sg = float(nc.accel_sigma_mps2), float(nc.gyro_sigma_rps)
        self.gate = float(nc.gate_chi2)
        self.phi = np.asarray(fb.cw_stm(self.n, self.dt))
        self.gamma = np.asarray(fb.cw_accel_response(self.n, self.dt))
        th = 0.5 * self.n * self.dt
        self.rz = np.array([[1.0, th, 0.0], [-th, 1.0, 0.0], [0.0, 0.0, 1.0]])  # the Hill frame's half-step turn
        self.hill = qexp(np.array([0.0, 0.0, -self.n * self.dt]))
        self.G = np.zeros((9, 6))
        self.G[0:6, 0:3] = self.gamma
        self.G[6:9, 3:6] = self.dt * np.eye(3)
        self.Qu_inv = np.diag([1.0 / self.sa**2] * 3 + [1.0 / self.sg**2] * 3)
        self.Q = self.G @ np.diag([self.sa**2] * 3 + [self.sg**2] * 3) @ self.G.T
        p = cfg.profile
        self.pos_frac, self.att_sigma = float(p.pose_pos_frac), float(p.pose_att_sigma_rad)
        self.v0_sigma = float(cfg.v0_sigma_mps)
        self.latency = float(p.pose_latency_s)
        self.pose_every = int(round(cfg.pose_period_s / cfg.dt_s))

    def a_mid(self, a, w):
        return a + 0.5 * self.dt * np.cross(w, a)

    def coupling(self, q, a, w) -> np.ndarray:
        """d a_hill / d dtheta (3x3)."""
        return -self.rz @ rotmat(q) @ skew(self.a_mid(a, w))

    def F(self, q, a, w) -> np.ndarray:
        F = np.zeros((9, 9))
        F[0:6, 0:6] = self.phi
        F[0:6, 6:9] = self.gamma @ self.coupling(q, a, w)
        F[6:9, 6:9] = rotmat(qexp(w * self.dt)).T
        return F

    def R(self, r_range_m: float) -> np.ndarray:
        s = self.pos_frac * max(r_range_m, MIN_RANGE_M)
        return np.diag([s * s] * 3 + [self.att_sigma**2] * 3)

    def pose_information(self, r) -> np.ndarray:
        """Fisher information (9x9) of one pose at the true position r."""
        rho = float(np.linalg.norm(r))
        s = self.pos_frac * max(rho, MIN_RANGE_M)
        J = np.zeros((9, 9))
        J[0:3, 0:3] = np.eye(3) / s**2
        if rho > MIN_RANGE_M:  # the noise level follows the true range: 1/2 tr(R^-1 dR R^-1 dR)
            J[0:3, 0:3] += 6.0 * np.outer(r, r) / rho**4
        J[6:9, 6:9] = np.eye(3) / self.att_sigma**2
        return J

    def propagate(self, x, a, w):
        """(r, v, q) one step on, the flight filter's mean dynamics."""
        r, v, q = x
        ah = self.rz @ (rotmat(q) @ self.a_mid(a, w))
        rv = self.phi @ np.concatenate([r, v]) + self.gamma @ ah
        return rv[0:3], rv[3:6], qmul(qmul(self.hill, q), qexp(w * self.dt))


# --------------------------------------------------------------------------- truth along each run


def _truth_terms(run: DockingRun, m: Model, cfg: ScenarioConfig):
    """Per step k (0..K-1) of one run: F_k and the block dB_k's ingredients
    (C_k, A_k) at the truth; per row: the pose information."""
    forces, _ = cfg.truth_vehicle.config_table()
    f_b = forces[np.asarray(run.config, int)] / cfg.truth_vehicle.mass_kg
    K = len(run.config)
    C = np.empty((K, 3, 3))
    A = np.empty((K, 3, 3))
    for k in range(K):
        w = 0.5 * (run.w_true[k] + run.w_true[k + 1])
        C[k] = m.coupling(run.q_true[k], f_b[k], w)
        A[k] = rotmat(qexp(w * m.dt)).T
    Jz = np.array([m.pose_information(r) for r in run.r_true])
    return C, A, Jz


def _is_capture(k: int, m: Model) -> bool:
    return k > 0 and k % m.pose_every == 0


def _delivered_capture(k: int, m: Model) -> int:
    """The latest capture row whose pose is delivered by row k (0: the start pose)."""
    lag = int(np.ceil(m.latency / m.dt - 1e-9))
    c = ((k - lag) // m.pose_every) * m.pose_every
    return max(c, 0)


def _recursion(m: Model, J0, Fbar, Mk, Jz, K: int) -> np.ndarray:
    """Bound (K+1, 9, 9) by the recursion of the module docstring; Fbar, Mk
    (K, 9, 9) per step, Jz (K+1, 9, 9) per row (used at capture rows)."""
    Jf = np.empty((K + 1, 9, 9))
    Jf[0] = J0
    for k in range(K):
        P = np.linalg.inv(Jf[k] + Mk[k])
        Jp = np.linalg.inv(m.Q + Fbar[k] @ P @ Fbar[k].T)
        Jf[k + 1] = Jp + (Jz[k + 1] if _is_capture(k + 1, m) else 0.0)
    B = np.linalg.inv(Jf)
    if m.latency <= 0.0:
        return B
    out = np.empty_like(B)
    for k in range(K + 1):
        c = _delivered_capture(k, m)
        J = Jf[c]
        for j in range(c, k):  # propagate without the poses not yet delivered
            P = np.linalg.inv(J + Mk[j])
            J = np.linalg.inv(m.Q + Fbar[j] @ P @ Fbar[j].T)
        out[k] = np.linalg.inv(J)
    return out


def _prior(m: Model, r0) -> np.ndarray:
    J0 = m.pose_information(r0)
    J0[3:6, 3:6] = np.eye(3) / m.v0_sigma**2
    return J0


def pcrb(runs: list[DockingRun], cfg: ScenarioConfig) -> dict:
    """The ensemble bound and the per-trajectory bound, per 10 Hz row."""
    m = Model(cfg)
    terms = [_truth_terms(r, m, cfg) for r in runs]
    lengths = np.array([len(r.config) for r in runs])
    K = int(lengths.max())
    Fbar = np.zeros((K, 9, 9))
    Mk = np.zeros((K, 9, 9))
    Jz = np.zeros((K + 1, 9, 9))
    active = np.array([int(np.sum(lengths >= k)) for k in range(K + 1)])
    for k in range(K):
        on = [i for i in range(len(runs)) if lengths[i] >= k + 1]
        C = np.array([terms[i][0][k] for i in on])
        A = np.array([terms[i][1][k] for i in on])
        Cm, Am = C.mean(0), A.mean(0)
        Fbar[k, 0:6, 0:6] = m.phi
        Fbar[k, 0:6, 6:9] = m.gamma @ Cm
        Fbar[k, 6:9, 6:9] = Am
        dB = np.concatenate([C - Cm, (A - Am) / m.dt], axis=1)  # (n, 6, 3): the attitude columns
        Mk[k, 6:9, 6:9] = np.einsum("nai,ab,nbj->ij", dB, m.Qu_inv, dB) / len(on)
        Jz[k + 1] = np.mean([terms[i][2][k + 1] for i in on], axis=0)
    J0 = np.mean([_prior(m, r.r_true[0]) for r in runs], axis=0)
    B = _recursion(m, J0, Fbar, Mk, Jz, K)
    # Per trajectory: the same recursion on one run's own terms.
    cond = np.zeros((K + 1, 9))
    for i, r in enumerate(runs):
        C, A, Jzi = terms[i]
        Ki = lengths[i]
        Fi = np.zeros((Ki, 9, 9))
        Fi[:, 0:6, 0:6] = m.phi
        Fi[:, 0:6, 6:9] = np.einsum("ab,kbc->kac", m.gamma, C)
        Fi[:, 6:9, 6:9] = A
        Bi = _recursion(m, _prior(m, r.r_true[0]), Fi, np.zeros((Ki, 9, 9)), Jzi, Ki)
        cond[: Ki + 1] += np.diagonal(Bi, axis1=1, axis2=2)
    cond /= np.maximum(active, 1)[:, None]
    # How much the spread of F over the runs adds (M_k) against the bound's own information.
    m_rel = float(np.max([np.linalg.norm(Mk[k]) / np.linalg.norm(np.linalg.inv(B[k])) for k in range(K)]))
    return {
        "t": np.arange(K + 1) * m.dt,
        "active": active,
        "bound": B,
        "bound_diag": np.diagonal(B, axis1=1, axis2=2).copy(),
        "conditional_diag": cond,
        "spread_term_rel_max": m_rel,
    }


# --------------------------------------------------------------------------- filters on the logged data


def _poses_by_row(run: DockingRun, dt: float) -> dict:
    """Row of delivery -> list of (capture time, r, q) delivered there."""
    u = run.updates
    out: dict[int, list] = {}
    for j in range(len(u.t_capture)):
        out.setdefault(int(round(u.t_fused[j] / dt)), []).append((float(u.t_capture[j]), u.r_meas[j], u.q_meas[j]))
    return out


def _run_flight_filter(run: DockingRun, m: Model, cfg: ScenarioConfig, float_build: bool):
    import fsw_bindings as fb

    f = (fb.NavUkfFloat if float_build else fb.NavUkf)(nav_config(cfg))
    x0 = run.est[0]
    f.init(0.0, x0[0:3], x0[3:6], x0[6:10] / np.linalg.norm(x0[6:10]), run.P[0])
    poses = _poses_by_row(run, m.dt)
    K = len(run.config)
    est = np.empty((K + 1, 10))
    P = np.empty((K + 1, 9, 9))
    est[0], P[0] = f.state(), f.P
    for k in range(1, K + 1):
        f.predict(float(run.imu_t[k - 1]), run.imu_accel[k - 1], run.imu_gyro[k - 1])
        for tc, r, q in poses.get(k, []):
            f.update_pose(tc, r, q / np.linalg.norm(q), m.R(float(np.linalg.norm(f.r_hill_m))))
        est[k], P[k] = f.state(), f.P
    return est, P


class Ekf:
    """Multiplicative extended Kalman filter on the flight filter's model."""

    def __init__(self, m: Model, x0, P0):
        self.m = m
        self.r, self.v, self.q = x0[0:3].copy(), x0[3:6].copy(), x0[6:10] / np.linalg.norm(x0[6:10])
        self.P = P0.copy()

    def predict(self, a, w):
        F = self.m.F(self.q, a, w)
        self.r, self.v, self.q = self.m.propagate((self.r, self.v, self.q), a, w)
        self.P = F @ self.P @ F.T + self.m.Q

    def update(self, r_meas, q_meas, R):
        y = np.concatenate([r_meas - self.r, boxminus(q_meas, self.q)])
        H = np.zeros((6, 9))
        H[0:3, 0:3] = np.eye(3)
        H[3:6, 6:9] = np.eye(3)
        S = H @ self.P @ H.T + R
        if self.m.gate > 0 and y @ np.linalg.solve(S, y) > self.m.gate:
            return
        K = np.linalg.solve(S, H @ self.P).T
        dx = K @ y
        self.r, self.v, self.q = self.r + dx[0:3], self.v + dx[3:6], boxplus(self.q, dx[6:9])
        IKH = np.eye(9) - K @ H
        self.P = IKH @ self.P @ IKH.T + K @ R @ K.T

    def state(self):
        return np.concatenate([self.r, self.v, self.q])


def _run_ekf(run: DockingRun, m: Model):
    f = Ekf(m, run.est[0], run.P[0])
    poses = _poses_by_row(run, m.dt)
    K = len(run.config)
    est = np.empty((K + 1, 10))
    P = np.empty((K + 1, 9, 9))
    est[0], P[0] = f.state(), f.P
    for k in range(1, K + 1):
        f.predict(run.imu_accel[k - 1], run.imu_gyro[k - 1])
        for _, r, q in poses.get(k, []):  # poses on time (latency 0: checked by the caller)
            f.update(r, q / np.linalg.norm(q), m.R(float(np.linalg.norm(f.r))))
        est[k], P[k] = f.state(), f.P
    return est, P


def _run_filterpy(run: DockingRun, m: Model):
    """FilterPy's UKF; its attitude is an absolute rotation vector. Returns the
    estimate as [r, v, q] and P over [r, v, rotation vector]."""
    from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

    def fx(x, dt, accel=np.zeros(3), omega=np.zeros(3)):
        r, v, q = m.propagate((x[0:3], x[3:6], qexp(x[6:9])), accel, omega)
        return np.concatenate([r, v, qlog(q)])

    def hx(x):
        return np.concatenate([x[0:3], x[6:9]])

    pts = MerweScaledSigmaPoints(9, alpha=1.0, beta=2.0, kappa=0.0)
    ukf = UnscentedKalmanFilter(dim_x=9, dim_z=6, dt=m.dt, fx=fx, hx=hx, points=pts)
    x0 = run.est[0]
    ukf.x = np.concatenate([x0[0:6], qlog(x0[6:10])])
    ukf.P = run.P[0].copy()
    ukf.Q = m.Q.copy()
    poses = _poses_by_row(run, m.dt)
    K = len(run.config)
    est = np.empty((K + 1, 10))
    P = np.empty((K + 1, 9, 9))

    def snap(k):
        est[k] = np.concatenate([ukf.x[0:6], qexp(ukf.x[6:9])])
        P[k] = ukf.P

    snap(0)
    for k in range(1, K + 1):
        ukf.predict(accel=run.imu_accel[k - 1], omega=run.imu_gyro[k - 1])
        for _, r, q in poses.get(k, []):
            ukf.update(np.concatenate([r, qlog(q)]), R=m.R(float(np.linalg.norm(ukf.x[0:3]))))
        snap(k)
    return est, P


def filter_errors(run: DockingRun, kind: str, m: Model, cfg: ScenarioConfig):
    """(errors (K+1, 9) [r, v, body-frame attitude], NEES (K+1,), diag P (K+1, 9)) of one filter on one run."""
    if kind == "ukf":
        est, P = run.est, run.P
    elif kind == "ukf_float":
        est, P = _run_flight_filter(run, m, cfg, float_build=True)
    elif kind == "ekf":
        est, P = _run_ekf(run, m)
    elif kind == "filterpy_ukf":
        est, P = _run_filterpy(run, m)
    else:
        raise ValueError(f"unknown filter {kind!r}")
    n = len(est)
    e = np.empty((n, 9))
    e_own = np.empty((n, 9))  # in the filter's own attitude coordinates, for NEES
    for k in range(n):
        e[k, 0:3] = run.r_true[k] - est[k, 0:3]
        e[k, 3:6] = run.v_true[k] - est[k, 3:6]
        e[k, 6:9] = boxminus(run.q_true[k], est[k, 6:10])
        e_own[k] = e[k]
        if kind == "filterpy_ukf":
            e_own[k, 6:9] = qlog(run.q_true[k]) - qlog(est[k, 6:10])
    nees = np.einsum("ki,ki->k", e_own, np.linalg.solve(P, e_own[:, :, None])[:, :, 0])
    return e, nees, np.diagonal(P, axis1=1, axis2=2).copy()


# --------------------------------------------------------------------------- figure of merit


def window(bound: dict, n_runs: int, t_conv_s: float = T_CONV_S) -> np.ndarray:
    """Rows after convergence while at least half the runs fly."""
    return (bound["t"] >= t_conv_s - 1e-9) & (bound["active"] >= max(1, n_runs // 2))


def ratios(errors: list[np.ndarray], bound_diag: np.ndarray, W: np.ndarray, rng: np.random.Generator) -> dict:
    """RMSE / sqrt(PCRB) per block and per axis over W, pooled over the runs,
    with a bootstrap interval over the runs (module docstring)."""
    se = np.zeros((len(errors), 9))  # per run: sum over its window rows of e^2
    sb = np.zeros((len(errors), 9))  # and of the bound at those rows
    for i, e in enumerate(errors):
        w = W[: len(e)]
        se[i] = np.sum(e[w] ** 2, axis=0)
        sb[i] = np.sum(bound_diag[: len(e)][w], axis=0)

    def fom(idx):
        a, b = se[idx].sum(0), sb[idx].sum(0)
        out = {
            blk: float(np.sqrt(a[3 * j : 3 * j + 3].sum() / b[3 * j : 3 * j + 3].sum())) for j, blk in enumerate(BLOCKS)
        }
        out["axes"] = np.sqrt(a / b).tolist()
        return out

    all_idx = np.arange(len(errors))
    res = fom(all_idx)
    boots = [fom(rng.integers(0, len(errors), len(errors))) for _ in range(BOOTSTRAP)]
    res["interval95"] = {blk: [float(np.percentile([b[blk] for b in boots], q)) for q in (2.5, 97.5)] for blk in BLOCKS}
    return res


def rmse_per_row(errors: list[np.ndarray], n_rows: int) -> np.ndarray:
    """(n_rows, 3): RMSE per block (over the three axes and the runs flying at each row)."""
    s = np.zeros((n_rows, 9))
    c = np.zeros(n_rows)
    for e in errors:
        s[: len(e)] += e**2
        c[: len(e)] += 1
    mse = s / np.maximum(c, 1)[:, None]
    return np.sqrt(np.stack([mse[:, 3 * j : 3 * j + 3].mean(1) for j in range(3)], 1))


def compare(runs: list[DockingRun], cfg: ScenarioConfig, filters=FILTERS, t_conv_s: float = T_CONV_S, seed: int = 0):
    """The bound, each filter's errors and NEES on the same runs, the figures of merit."""
    m = Model(cfg)
    if m.latency > 0 and any(f in ("ekf", "filterpy_ukf") for f in filters):
        raise ValueError("the EKF and FilterPy comparisons fuse poses on time: pose latency must be 0")
    b = pcrb(runs, cfg)
    W = window(b, len(runs), t_conv_s)
    n_rows = len(b["t"])
    out = {
        "runs": len(runs),
        "run_seeds": [int(r.summary.seed) for r in runs],
        "t_conv_s": t_conv_s,
        "window_s": [float(b["t"][W][0]), float(b["t"][W][-1])] if W.any() else None,
        "pose_latency_s": m.latency,
        "spread_term_rel_max": b["spread_term_rel_max"],
        "bound_sqrt_in_window": {
            blk: float(np.sqrt(np.mean(b["bound_diag"][W][:, 3 * j : 3 * j + 3]))) for j, blk in enumerate(BLOCKS)
        },
        "conditional_over_ensemble": {
            blk: float(
                np.sqrt(
                    np.sum(b["conditional_diag"][W][:, 3 * j : 3 * j + 3] * b["active"][W][:, None])
                    / np.sum(b["bound_diag"][W][:, 3 * j : 3 * j + 3] * b["active"][W][:, None])
                )
            )
            for j, blk in enumerate(BLOCKS)
        },
        "filters": {},
    }
    series = {"t": b["t"], "active": b["active"], "bound_sqrt": None, "rmse": {}}
    series["bound_sqrt"] = np.sqrt(np.stack([b["bound_diag"][:, 3 * j : 3 * j + 3].mean(1) for j in range(3)], 1))
    series["conditional_sqrt"] = np.sqrt(
        np.stack([b["conditional_diag"][:, 3 * j : 3 * j + 3].mean(1) for j in range(3)], 1)
    )
    dof_band = [float(chi2.ppf(0.025, 9 * len(runs)) / len(runs)), float(chi2.ppf(0.975, 9 * len(runs)) / len(runs))]
    for f in filters:
        errs, nees, pdiag = [], [], []
        for r in runs:
            e, nz, pd = filter_errors(r, f, m, cfg)
            errs.append(e)
            nees.append(nz)
            pdiag.append(pd)
        rng = np.random.default_rng(seed)
        res = ratios(errs, b["bound_diag"], W, rng)
        # The filter's own variance against the bound, pooled the same way.
        own = ratios([np.sqrt(pd) for pd in pdiag], b["bound_diag"], W, np.random.default_rng(seed))
        res["sqrt_P_over_bound"] = {blk: own[blk] for blk in BLOCKS}
        nw = np.concatenate([nz[W[: len(nz)]] for nz in nees])
        res["nees_mean_window"] = float(np.mean(nw))
        res["nees_mean_all"] = float(np.mean(np.concatenate([nz[10:] for nz in nees])))
        res["nees_band"] = dof_band
        res["nees_in_band"] = bool(dof_band[0] <= res["nees_mean_window"] <= dof_band[1])
        out["filters"][f] = res
        series["rmse"][f] = rmse_per_row(errs, n_rows)
    every = m.pose_every
    out["series_1hz"] = {
        "t_s": series["t"][::every].tolist(),
        "runs_flying": series["active"][::every].tolist(),
        "bound_sqrt_per_axis": {blk: series["bound_sqrt"][::every, j].tolist() for j, blk in enumerate(BLOCKS)},
        "rmse_per_axis": {
            f: {blk: rm[::every, j].tolist() for j, blk in enumerate(BLOCKS)} for f, rm in series["rmse"].items()
        },
    }
    return out, series


def plot(series: dict, summary: dict, folder) -> list[str]:
    from bench.report import matplotlib_agg, report_dir

    plt = matplotlib_agg()
    out = report_dir(folder)
    t = series["t"]
    fig, axes = plt.subplots(4, 1, figsize=(8, 10), sharex=True, gridspec_kw={"height_ratios": [3, 3, 3, 1]})
    units = {"pos": "m", "vel": "m/s", "att": "rad"}
    styles = {"ukf": "-", "ukf_float": ":", "filterpy_ukf": "--", "ekf": "-."}
    for j, blk in enumerate(BLOCKS):
        ax = axes[j]
        for f, rm in series["rmse"].items():
            ax.semilogy(t[1:], rm[1:, j], styles.get(f, "-"), lw=0.9, label=f"RMSE {f}")
        ax.semilogy(t[1:], series["bound_sqrt"][1:, j], "k", lw=1.6, label="sqrt(PCRB)")
        ax.semilogy(t[1:], series["conditional_sqrt"][1:, j], color="0.5", lw=0.8, label="per-trajectory bound")
        ax.set_ylabel(f"{blk} per axis [{units[blk]}]")
        if summary.get("window_s"):
            ax.axvspan(*summary["window_s"], color="0.92", zorder=0)
    axes[0].legend(fontsize=7, ncol=2, loc="upper right")
    axes[0].set_title(f"RMSE per axis against the posterior Cramer-Rao bound, {summary['runs']} docking runs")
    axes[3].plot(t, series["active"], "k", lw=0.8)
    axes[3].set(ylabel="runs flying", xlabel="time [s]")
    fig.tight_layout()
    p1 = out / "nav_pcrb.png"
    fig.savefig(p1, dpi=120)
    plt.close(fig)
    # The ratio over time.
    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for j, blk in enumerate(BLOCKS):
        for f, rm in series["rmse"].items():
            axes[j].plot(t[1:], rm[1:, j] / series["bound_sqrt"][1:, j], styles.get(f, "-"), lw=0.8, label=f)
        axes[j].axhline(1.0, color="k", lw=0.8)
        axes[j].axhline(1.1, color="k", ls="--", lw=0.6)
        axes[j].set_ylabel(f"{blk}: RMSE / sqrt(PCRB)")
        axes[j].set_ylim(0.5, 2.0)
    axes[0].legend(fontsize=7, ncol=4)
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    p2 = out / "nav_pcrb_ratio.png"
    fig.savefig(p2, dpi=120)
    plt.close(fig)
    return [str(p1), str(p2)]
