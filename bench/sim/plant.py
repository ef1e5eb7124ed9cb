"""Truth plant: the inspector as a rigid body relative to the host.

State (Hill frame H: x radial, y along-track, z orbit normal; origin at the
host's centre of mass, host in a circular orbit of radius a):
    r_hill_m, v_hill_mps   inspector position and velocity relative to the host
    q_hb                   [w, x, y, z], rotates body vectors into H
    omega_bi_b_rps         body rate with respect to inertial space, body axes

Translation, with f the thrust acceleration in H:
  * "cw":        x'' = 3n^2 x + 2n y' + f_x,  y'' = -2n x' + f_y,  z'' = -n^2 z + f_z
  * "nonlinear": exact relative motion about a circular reference orbit,
        x'' = 2n y' + n^2 (a + x) - mu (a + x) / rd^3 + f_x
        y'' = -2n x' + n^2 y      - mu y / rd^3       + f_y
        z'' =                     - mu z / rd^3       + f_z,
    rd = |(a + x, y, z)|, with n^2 a = mu / a^2 (checked against the inertial
    two-body integration of bench/sim/orbit.py in tests/py/test_plant.py).
Rotation (Euler): J w' = -w x (J w) + tau, w = omega_BI_B. The Hill frame
turns at n about its z axis, so the rate of B relative to H is
omega_BH_B = omega_BI_B - C_BH [0, 0, n] and q_hb' = 1/2 q_hb (x) [0, omega_BH_B].

Thrust is held constant (in the body frame) over each control interval and
the whole state is integrated with fixed-step RK4 at ``substep_s``.

Physical effects (``PlantEffects``, off by default; docs/EFFECTS.md): host
orbit eccentricity, differential J2 and drag in the translation; a flexible
appendage mode and fuel slosh as extra states; propellant depletion; the
accelerometer's lever arm from a centre-of-mass offset. With ``effects=None``
the plant runs the rigid-body equations above, unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bench.sim import orbit
from bench.sim.vehicle import Vehicle
from bench.so3 import qconj, qexp, qlog, qmul, qnormalize, rotmat

ALTITUDE_M = 500e3
ORBIT_RADIUS_M = orbit.EARTH_RADIUS + ALTITUDE_M
N_RADPS = orbit.orbit_rate(ORBIT_RADIUS_M)


def cross3(a, b):
    """a x b for 3-vectors; the same arithmetic as np.cross, without its overhead."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


# --- plant ------------------------------------------------------------------


@dataclass
class PlantState:
    t_s: float
    r_hill_m: np.ndarray
    v_hill_mps: np.ndarray
    q_hb: np.ndarray
    omega_bi_b_rps: np.ndarray

    def copy(self) -> "PlantState":
        return PlantState(
            self.t_s, self.r_hill_m.copy(), self.v_hill_mps.copy(), self.q_hb.copy(), self.omega_bi_b_rps.copy()
        )


@dataclass
class StepResult:
    """What happened over one control interval (the IMU's view of it)."""

    dt_s: float
    specific_force_b_mps2: np.ndarray  # thrust / m, body frame, mean over the interval
    omega_mean_bi_b_rps: np.ndarray  # Log(q_IB(t0)^-1 q_IB(t1)) / dt: mean inertial rate


EARTH_J2 = 1.08262668e-3


@dataclass
class PlantEffects:
    """Physics the nominal (CW, rigid, constant-mass) model leaves out. Zero
    means off. Each term is documented in docs/EFFECTS.md."""

    # Host on a Kepler orbit of semi-major axis ``radius_m``, eccentricity e,
    # true anomaly f0 at t = 0; the Hill frame follows the host (its rate
    # theta_dot(t) is no longer n).
    host_eccentricity: float = 0.0
    host_true_anomaly0_rad: float = 0.0
    # J2 acting on host and inspector: the differential J2 acceleration, host
    # on the circular reference orbit of inclination ``j2_inclination_rad``,
    # argument of latitude n t.
    j2: float = 0.0
    j2_inclination_rad: float = np.deg2rad(51.6)
    # Differential drag: a = -1/2 rho v^2 (B_inspector - B_host) along-track.
    # The inspector's own drag, -1/2 rho v^2 B_inspector along-track, is a
    # non-gravitational force on it: its accelerometer senses it
    # (B_inspector = diff_ballistic_m2pkg + host_ballistic_m2pkg).
    diff_ballistic_m2pkg: float = 0.0
    host_ballistic_m2pkg: float = 0.0
    air_density_kgpm3: float = 5e-13
    # Propellant use [kg per valve-second].
    mass_flow_kgps_per_valve: float = 0.0
    # Accelerometer position relative to the centre of mass (body, m).
    imu_offset_b_m: np.ndarray | None = None
    # Flexible appendage: one mode coupled to the body rotation about
    # ``flex_axis_b`` (participation fraction delta^T J^-1 delta), started
    # with the body-angle amplitude ``flex_amplitude_rad``; ``flex_freq_hz``
    # is the coupled (observed) frequency.
    flex_freq_hz: float = 0.0
    flex_amplitude_rad: float = 0.0
    flex_axis_b: tuple = (0.0, 0.0, 1.0)
    flex_participation: float = 1e-3  # light: the mode shows through its swing, not as a change of inertia
    flex_damping: float = 0.005
    # Fuel slosh: a mass on a damped spring in the tank at the centre of mass;
    # the rigid vehicle (the accelerometer's and the LEDs' body) has the rest.
    slosh_mass_kg: float = 0.0
    slosh_freq_hz: float = 0.3
    slosh_damping: float = 0.05


@dataclass
class Plant:
    """Truth plant. ``dynamics`` is "cw" or "nonlinear"."""

    state: PlantState
    vehicle: Vehicle = field(default_factory=Vehicle)
    dynamics: str = "nonlinear"
    substep_s: float = 0.01
    radius_m: float = ORBIT_RADIUS_M
    mu: float = orbit.MU_EARTH
    effects: PlantEffects | None = None

    def __post_init__(self):
        if self.dynamics not in ("cw", "nonlinear"):
            raise ValueError(f"dynamics must be 'cw' or 'nonlinear', not {self.dynamics!r}")
        self.n_radps = orbit.orbit_rate(self.radius_m, self.mu)
        self._j = np.asarray(self.vehicle.inertia_kgm2, dtype=float)
        self._j_inv = np.linalg.inv(self._j)
        self.mass_kg = float(self.vehicle.mass_kg)
        if self.effects is not None:
            self._init_effects()

    def q_ib(self, t_s: float, q_hb) -> np.ndarray:
        """Body-to-inertial quaternion; inertial axes = Hill axes at t = 0."""
        if self.effects is not None and self.effects.host_eccentricity > 0.0:
            return qmul(qexp([0.0, 0.0, self._host(t_s)[4]]), q_hb)
        return qmul(qexp([0.0, 0.0, self.n_radps * t_s]), q_hb)

    def translational_accel(self, r, v, f_hill):
        n = self.n_radps
        if self.dynamics == "cw":
            return np.array([3 * n * n * r[0] + 2 * n * v[1], -2 * n * v[0], -n * n * r[2]]) + f_hill
        a = self.radius_m
        rd = np.sqrt((a + r[0]) ** 2 + r[1] ** 2 + r[2] ** 2)
        k = self.mu / rd**3
        # n^2 (a + x) - mu (a + x) / rd^3 written as (n^2 - k)(a + x): both terms
        # are ~8 m/s^2 and cancel; the difference stays accurate to ~1e-15 m/s^2.
        return (
            np.array(
                [
                    2 * n * v[1] + (n * n - k) * (a + r[0]),
                    -2 * n * v[0] + (n * n - k) * r[1],
                    -k * r[2],
                ]
            )
            + f_hill
        )

    def _deriv(self, y, force_b, torque_b):
        r, v, q, w = y[0:3], y[3:6], y[6:10], y[10:13]
        c_hb = rotmat(q / np.linalg.norm(q))
        acc = self.translational_accel(r, v, c_hb @ force_b / self.mass_kg)
        w_bh = w - c_hb.T @ np.array([0.0, 0.0, self.n_radps])
        qdot = 0.5 * qmul(q, np.concatenate([[0.0], w_bh]))
        wdot = self._j_inv @ (torque_b - cross3(w, self._j @ w))
        return np.concatenate([v, acc, qdot, wdot])

    def rk4_reference(self, y, force_b, torque_b, h: float, n_sub: int) -> np.ndarray:
        """The same integration as _rk4_floats with numpy vectors and _deriv
        (the readable form; tests check the two agree)."""
        y = np.asarray(y, float)
        for _ in range(n_sub):
            k1 = self._deriv(y, force_b, torque_b)
            k2 = self._deriv(y + 0.5 * h * k1, force_b, torque_b)
            k3 = self._deriv(y + 0.5 * h * k2, force_b, torque_b)
            k4 = self._deriv(y + h * k3, force_b, torque_b)
            y = y + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
            y[6:10] /= np.linalg.norm(y[6:10])
        return y

    def _rk4_floats(self, y: list, f: list, tau: list, h: float, n_sub: int) -> list:
        """Fixed-step RK4 of the rigid-body plant (no effects) on Python
        floats: _deriv's arithmetic without numpy's per-call overhead on
        13-element vectors (the bench's hot loop; about 10x faster)."""
        n = self.n_radps
        nonlinear = self.dynamics == "nonlinear"
        a, mu, inv_m = self.radius_m, self.mu, 1.0 / self.mass_kg
        (j00, j01, j02), (j10, j11, j12), (j20, j21, j22) = self._j.tolist()
        (i00, i01, i02), (i10, i11, i12), (i20, i21, i22) = self._j_inv.tolist()
        fx, fy, fz = f
        tx, ty, tz = tau
        sqrt = math.sqrt

        def deriv(y):
            x, yy, z, vx, vy, vz, qw, qx, qy, qz, wx, wy, wz = y
            qn = 1.0 / sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
            w_, x_, y_, z_ = qw * qn, qx * qn, qy * qn, qz * qn
            c00 = 1 - 2 * (y_ * y_ + z_ * z_)
            c01 = 2 * (x_ * y_ - w_ * z_)
            c02 = 2 * (x_ * z_ + w_ * y_)
            c10 = 2 * (x_ * y_ + w_ * z_)
            c11 = 1 - 2 * (x_ * x_ + z_ * z_)
            c12 = 2 * (y_ * z_ - w_ * x_)
            c20 = 2 * (x_ * z_ - w_ * y_)
            c21 = 2 * (y_ * z_ + w_ * x_)
            c22 = 1 - 2 * (x_ * x_ + y_ * y_)
            ahx = (c00 * fx + c01 * fy + c02 * fz) * inv_m
            ahy = (c10 * fx + c11 * fy + c12 * fz) * inv_m
            ahz = (c20 * fx + c21 * fy + c22 * fz) * inv_m
            if nonlinear:
                rd = sqrt((a + x) ** 2 + yy**2 + z**2)
                k = mu / rd**3
                ax = 2 * n * vy + (n * n - k) * (a + x) + ahx
                ay = -2 * n * vx + (n * n - k) * yy + ahy
                az = -k * z + ahz
            else:
                ax = 3 * n * n * x + 2 * n * vy + ahx
                ay = -2 * n * vx + ahy
                az = -n * n * z + ahz
            bx, by, bz = wx - n * c20, wy - n * c21, wz - n * c22
            qdw = 0.5 * (-qx * bx - qy * by - qz * bz)
            qdx = 0.5 * (qw * bx + qy * bz - qz * by)
            qdy = 0.5 * (qw * by - qx * bz + qz * bx)
            qdz = 0.5 * (qw * bz + qx * by - qy * bx)
            hx = j00 * wx + j01 * wy + j02 * wz
            hy = j10 * wx + j11 * wy + j12 * wz
            hz = j20 * wx + j21 * wy + j22 * wz
            mx = tx - (wy * hz - wz * hy)
            my = ty - (wz * hx - wx * hz)
            mz = tz - (wx * hy - wy * hx)
            return (
                vx,
                vy,
                vz,
                ax,
                ay,
                az,
                qdw,
                qdx,
                qdy,
                qdz,
                i00 * mx + i01 * my + i02 * mz,
                i10 * mx + i11 * my + i12 * mz,
                i20 * mx + i21 * my + i22 * mz,
            )

        h2, h6 = 0.5 * h, h / 6.0
        for _ in range(n_sub):
            k1 = deriv(y)
            k2 = deriv([yi + h2 * ki for yi, ki in zip(y, k1)])
            k3 = deriv([yi + h2 * ki for yi, ki in zip(y, k2)])
            k4 = deriv([yi + h * ki for yi, ki in zip(y, k3)])
            y = [yi + h6 * (a1 + 2 * a2 + 2 * a3 + a4) for yi, a1, a2, a3, a4 in zip(y, k1, k2, k3, k4)]
            qn = 1.0 / sqrt(y[6] ** 2 + y[7] ** 2 + y[8] ** 2 + y[9] ** 2)
            y[6:10] = [c * qn for c in y[6:10]]
        return y

    def step(self, valves, dt_s: float) -> StepResult:
        """Advance by dt_s with the valve vector (8,) held open; returns the
        interval's mean specific force and mean inertial body rate."""
        force_b, torque_b = self.vehicle.wrench(valves)
        if self.effects is None or self.effects.mass_flow_kgps_per_valve <= 0.0:
            return self.step_wrench(force_b, torque_b, dt_s)
        # Propellant flows while the valves are open: the interval flies at the
        # mass of its midpoint (half the valve-seconds' propellant used before
        # it, the other half after), as bench/sim/vehicle_sim.py flies a step.
        used = self.effects.mass_flow_kgps_per_valve * float(np.sum(valves)) * dt_s
        self.mass_kg -= 0.5 * used
        res = self.step_wrench(force_b, torque_b, dt_s)
        self.mass_kg -= 0.5 * used
        return res

    def step_wrench(self, force_b_n, torque_b_nm, dt_s: float) -> StepResult:
        if self.effects is not None:
            return self._step_effects(np.asarray(force_b_n, float), np.asarray(torque_b_nm, float), dt_s)
        s = self.state
        force_b = np.asarray(force_b_n, dtype=float)
        q_ib0 = self.q_ib(s.t_s, s.q_hb)
        self.advance_rigid(force_b, torque_b_nm, dt_s)
        q_ib1 = self.q_ib(self.state.t_s, self.state.q_hb)
        omega_mean = qlog(qmul(qconj(q_ib0), q_ib1)) / dt_s
        return StepResult(dt_s, force_b / self.mass_kg, omega_mean)

    def advance_rigid(self, force_b_n, torque_b_nm, dt_s: float) -> None:
        """The state of the rigid-body plant (no effects) moved on by dt_s
        with the wrench held: step_wrench's integration without its
        StepResult (the mean specific force is the force over the mass; a
        caller that keeps the attitudes needs no mean rate)."""
        s = self.state
        y = np.concatenate([s.r_hill_m, s.v_hill_mps, s.q_hb, s.omega_bi_b_rps]).tolist()
        f = np.asarray(force_b_n, dtype=float).tolist()
        tau = np.asarray(torque_b_nm, dtype=float).tolist()
        n_sub = max(1, int(np.ceil(dt_s / self.substep_s - 1e-9)))
        y = np.array(self._rk4_floats(y, f, tau, dt_s / n_sub, n_sub))
        self.state = PlantState(s.t_s + dt_s, y[0:3].copy(), y[3:6].copy(), qnormalize(y[6:10]), y[10:13].copy())

    # --- physical effects (docs/EFFECTS.md) ---------------------------------

    def _init_effects(self):
        fx = self.effects
        # Internal states carried between steps: flex [eta, eta_dot], slosh [s (3), s_dot (3)].
        self._internal = np.zeros(8)
        e = float(fx.host_eccentricity)
        if not 0.0 <= e < 1.0:
            raise ValueError(f"host_eccentricity must be in [0, 1), not {e}")
        if e > 0.0:
            f0 = float(fx.host_true_anomaly0_rad)
            self._beta = e / (1.0 + np.sqrt(1.0 - e * e))
            e0 = f0 - 2.0 * np.arctan2(self._beta * np.sin(f0), 1.0 + self._beta * np.cos(f0))
            self._m0 = e0 - e * np.sin(e0)
            self._p = self.radius_m * (1.0 - e * e)
            self._f0 = 0.0
            self._f0 = self._host(0.0)[4]
        self._flex_on = fx.flex_freq_hz > 0.0 and fx.flex_amplitude_rad != 0.0
        if self._flex_on:
            axis = np.asarray(fx.flex_axis_b, float)
            axis = axis / np.linalg.norm(axis)
            delta = np.sqrt(fx.flex_participation * float(axis @ self._j @ axis)) * axis
            part = float(delta @ self._j_inv @ delta)
            # The coupled (observed) frequency is Omega / sqrt(1 - part).
            self._flex_omega = 2.0 * np.pi * fx.flex_freq_hz * np.sqrt(1.0 - part)
            m = np.zeros((4, 4))
            m[0:3, 0:3], m[0:3, 3], m[3, 0:3], m[3, 3] = self._j, delta, delta, 1.0
            self._flex_minv = np.linalg.inv(m)
            # Body angle swings by |J^-1 delta| eta (angular momentum exchange).
            self._internal[0] = fx.flex_amplitude_rad / np.linalg.norm(self._j_inv @ delta)
        self._slosh_on = fx.slosh_mass_kg > 0.0
        self._slosh_w = 2.0 * np.pi * fx.slosh_freq_hz
        q_dyn = 0.5 * fx.air_density_kgpm3 * (self.n_radps * self.radius_m) ** 2
        self._drag_y = -q_dyn * fx.diff_ballistic_m2pkg
        self._drag_insp_y = -q_dyn * (fx.diff_ballistic_m2pkg + fx.host_ballistic_m2pkg)

    @property
    def internal_state(self) -> np.ndarray:
        """[eta, eta_dot, slosh s_b (3), slosh s_dot_b (3)] (zeros without effects)."""
        return self._internal.copy() if self.effects is not None else np.zeros(8)

    def hill_rate_radps(self, t_s: float) -> float:
        """The Hill frame's inertial rotation rate at t (about its z axis): the
        host's true-anomaly rate on an eccentric orbit, else the mean motion.
        A body at rest in the Hill frame turns at this rate."""
        if self.effects is not None and self.effects.host_eccentricity > 0.0:
            return float(self._host(t_s)[2])
        return self.n_radps

    def _host(self, t_s: float):
        """Host on its Kepler orbit at t: (r_c, r_c_dot, theta_dot, theta_ddot,
        theta(t) - theta(0))."""
        e, a, mu = self.effects.host_eccentricity, self.radius_m, self.mu
        mean = self._m0 + self.n_radps * t_s
        ecc = mean
        for _ in range(30):
            d = (ecc - e * np.sin(ecc) - mean) / (1.0 - e * np.cos(ecc))
            ecc -= d
            if abs(d) < 1e-15:
                break
        f = ecc + 2.0 * np.arctan2(self._beta * np.sin(ecc), 1.0 - self._beta * np.cos(ecc))
        rc = a * (1.0 - e * np.cos(ecc))
        thd = np.sqrt(mu * self._p) / (rc * rc)
        rcd = np.sqrt(mu / self._p) * e * np.sin(f)
        return rc, rcd, thd, -2.0 * rcd * thd / rc, f - self._f0

    def _j2_accel_hill(self, t_s: float, r) -> np.ndarray:
        """J2 on the inspector minus J2 on the host (host on the circular
        reference orbit), Hill axes."""
        fx = self.effects
        u, inc = self.n_radps * t_s, fx.j2_inclination_rad
        xh = np.array([np.cos(u), np.cos(inc) * np.sin(u), np.sin(inc) * np.sin(u)])
        zh = np.array([0.0, -np.sin(inc), np.cos(inc)])
        c = np.column_stack([xh, np.cross(zh, xh), zh])  # Hill -> inertial
        rc = self.radius_m * xh

        def a_j2(p):
            rr = p @ p
            k = -1.5 * fx.j2 * self.mu * orbit.EARTH_RADIUS**2 / rr**2.5
            z2 = 5.0 * p[2] ** 2 / rr
            return k * np.array([p[0] * (1.0 - z2), p[1] * (1.0 - z2), p[2] * (3.0 - z2)])

        return c.T @ (a_j2(rc + c @ r) - a_j2(rc))

    def _deriv_effects(self, t_s, y, force_b, torque_b):
        fx = self.effects
        r, v, q, w = y[0:3], y[3:6], y[6:10], y[10:13]
        c_hb = rotmat(q / np.linalg.norm(q))
        m_rigid = self.mass_kg
        f_b = force_b
        if self._slosh_on:
            # Spring force of the slosh mass on the tank; the rigid part has the rest of the mass.
            sl, sld = y[15:18], y[18:21]
            spring = fx.slosh_mass_kg * (self._slosh_w**2 * sl + 2.0 * fx.slosh_damping * self._slosh_w * sld)
            f_b = force_b + spring
            m_rigid = self.mass_kg - fx.slosh_mass_kg
        a_b = f_b / m_rigid  # specific force of the rigid body
        f_hill = c_hb @ a_b
        if fx.host_eccentricity > 0.0:
            rc, _, thd, thdd, _ = self._host(t_s)
            rd = np.sqrt((rc + r[0]) ** 2 + r[1] ** 2 + r[2] ** 2)
            kd, kc = self.mu / rd**3, self.mu / rc**3
            acc = (
                np.array(
                    [
                        2 * thd * v[1] + thdd * r[1] + thd * thd * r[0] + (kc - kd) * rc - kd * r[0],
                        -2 * thd * v[0] - thdd * r[0] + thd * thd * r[1] - kd * r[1],
                        -kd * r[2],
                    ]
                )
                + f_hill
            )
        else:
            thd = self.n_radps
            acc = self.translational_accel(r, v, f_hill)
        if fx.j2 != 0.0:
            acc = acc + self._j2_accel_hill(t_s, r)
        if self._drag_y != 0.0:
            acc = acc + np.array([0.0, self._drag_y, 0.0])
        if self._drag_insp_y != 0.0:
            a_b = a_b + c_hb.T @ np.array([0.0, self._drag_insp_y, 0.0])  # sensed, not added again to acc
        w_bh = w - c_hb.T @ np.array([0.0, 0.0, thd])
        qdot = 0.5 * qmul(q, np.concatenate([[0.0], w_bh]))
        rhs = torque_b - cross3(w, self._j @ w)
        out = np.zeros(24)
        if self._flex_on:
            eta, etad = y[13], y[14]
            om = self._flex_omega
            acc4 = self._flex_minv @ np.concatenate([rhs, [-2.0 * fx.flex_damping * om * etad - om * om * eta]])
            out[10:13], out[13], out[14] = acc4[0:3], etad, acc4[3]
        else:
            out[10:13] = self._j_inv @ rhs
        if self._slosh_on:
            out[15:18] = y[18:21]
            out[18:21] = -(self._slosh_w**2 * y[15:18] + 2.0 * fx.slosh_damping * self._slosh_w * y[18:21]) - a_b
        out[0:3], out[3:6], out[6:10], out[21:24] = v, acc, qdot, a_b
        return out

    def _step_effects(self, force_b, torque_b, dt_s: float) -> StepResult:
        s = self.state
        q_ib0 = self.q_ib(s.t_s, s.q_hb)
        y = np.concatenate([s.r_hill_m, s.v_hill_mps, s.q_hb, s.omega_bi_b_rps, self._internal, np.zeros(3)])
        n_sub = max(1, int(np.ceil(dt_s / self.substep_s - 1e-9)))
        h = dt_s / n_sub
        for i in range(n_sub):
            t = s.t_s + i * h
            k1 = self._deriv_effects(t, y, force_b, torque_b)
            k2 = self._deriv_effects(t + 0.5 * h, y + 0.5 * h * k1, force_b, torque_b)
            k3 = self._deriv_effects(t + 0.5 * h, y + 0.5 * h * k2, force_b, torque_b)
            k4 = self._deriv_effects(t + h, y + h * k3, force_b, torque_b)
            y = y + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
            y[6:10] /= np.linalg.norm(y[6:10])
        t1 = s.t_s + dt_s
        w0 = s.omega_bi_b_rps
        self.state = PlantState(t1, y[0:3].copy(), y[3:6].copy(), qnormalize(y[6:10]), y[10:13].copy())
        self._internal = y[13:21].copy()
        q_ib1 = self.q_ib(t1, self.state.q_hb)
        omega_mean = qlog(qmul(qconj(q_ib0), q_ib1)) / dt_s
        f_mean = y[21:24] / dt_s
        rho = self.effects.imu_offset_b_m
        if rho is not None and np.any(rho != 0.0):
            # Accelerometer off the centre of mass: + alpha x rho + w x (w x rho),
            # alpha the interval's mean angular acceleration.
            rho = np.asarray(rho, float)
            w1 = self.state.omega_bi_b_rps
            alpha = (w1 - w0) / dt_s
            wm = 0.5 * (w0 + w1)
            f_mean = f_mean + np.cross(alpha, rho) + np.cross(wm, np.cross(wm, rho))
        return StepResult(dt_s, f_mean, omega_mean)
