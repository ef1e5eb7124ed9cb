"""Behaviour-based velocity potential-function docking controller.

Host geometry (Hill frame, host centre of mass at the origin): the host is a
0.40 m cube; its docking port is the centre of its -y face (trailing side),
``PORT_HILL_M`` = (0, -0.20, 0). The inspector docks with its +y face
(bench/sim/vehicle.py) and body axes aligned with the Hill axes (q_hb = 1), so
the docked centre of mass is ``DOCK_HILL_M`` = (0, -0.30, 0); the approach
axis is +y.

Every control interval (0.1 s) the controller, from the navigation estimate
(r, v, q) and the latest gyro samples (never the truth):
1. Translation, two behaviours blended on one attractive potential toward the
   docking point. With e = r - r_dock split into the axial distance d = -e_y
   (positive while short of the port) and the lateral offset e_lat:
     - "align":    v_lat = -k_lat e_lat, capped at v_lat_max;
     - "approach": closing speed clip(k_ax d, v_min, v_max) along +y, allowed
       only inside the approach cone |e_lat| <= max(lat_tol, cone * d);
       outside it the axial velocity is driven to zero (hold range).
   v_min > 0 keeps a slow closing speed to contact.
2. Rotation: hold q_des = 1 relative to Hill. omega_BH_des = -k_att
   boxminus(q_est, q_des) (capped), and omega_BI_des = omega_BH_des + C_BH
   [0, 0, n]. The measured rate is the mean of the last ``gyro_avg`` gyro
   samples (the gyro noise is as large as one valve's rate change).
3. Thruster selection: the desired velocity change over the interval,
   dv_des = C_BH (v_des - v_est) dt / tau_v and dw_des = (w_des - w_meas) dt / tau_w,
   is matched against the nominal effect of each of the 256 configurations,
   dv_k = F_k dt / m, dw_k = J^-1 tau_k dt, by minimising
   |(dv_des - dv_k) / dv1|^2 + w_rot |(dw_des - dw_k) / dw1|^2 + w_fuel (valves open),
   dv1 and dw1 being one valve's nominal changes.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

from bench.sim.plant import N_RADPS
from bench.sim.vehicle import ALL_VALVES, Vehicle
from bench.so3 import boxminus, rotmat

HOST_HALF_SIZE_M = 0.20
PORT_HILL_M = np.array([0.0, -HOST_HALF_SIZE_M, 0.0])
APPROACH_AXIS_HILL = np.array([0.0, 1.0, 0.0])
Q_DOCK_HB = np.array([1.0, 0.0, 0.0, 0.0])


def dock_point_hill_m(vehicle: Vehicle | None = None) -> np.ndarray:
    half = 0.10 if vehicle is None else float(np.max(np.abs(vehicle.positions_b_m[:, 1])))
    return PORT_HILL_M - half * APPROACH_AXIS_HILL


DOCK_HILL_M = dock_point_hill_m()


@dataclass
class ControllerParams:
    dt_s: float = 0.1
    v_max_mps: float = 0.010
    v_min_mps: float = 0.003
    k_ax_ps: float = 0.05
    k_lat_ps: float = 0.08
    v_lat_max_mps: float = 0.010
    lat_tol_m: float = 0.02
    cone: float = 0.35
    k_att_ps: float = 0.3
    w_bh_max_rps: float = 0.05
    tau_v_s: float = 0.5
    tau_w_s: float = 0.1
    w_rot: float = 1.0
    w_fuel: float = 0.3
    gyro_avg: int = 3
    n_radps: float = N_RADPS


@dataclass
class ControlDecision:
    config: int
    valves: np.ndarray
    v_des_hill_mps: np.ndarray
    omega_des_bi_b_rps: np.ndarray
    behaviour: str


@dataclass
class DockingController:
    vehicle: Vehicle = field(default_factory=Vehicle)  # the controller's nominal model
    params: ControllerParams = field(default_factory=ControllerParams)
    dock_hill_m: np.ndarray = field(default_factory=lambda: DOCK_HILL_M.copy())
    q_des_hb: np.ndarray = field(default_factory=lambda: Q_DOCK_HB.copy())

    def __post_init__(self):
        p = self.params
        f, tau = self.vehicle.config_table()
        self._dv = f * p.dt_s / self.vehicle.mass_kg  # (256, 3) body frame
        self._dw = tau @ np.linalg.inv(self.vehicle.inertia_kgm2).T * p.dt_s  # (256, 3)
        self._dv1 = self.vehicle.thrust_n * p.dt_s / self.vehicle.mass_kg
        self._dw1 = float(np.median(np.linalg.norm(self._dw[[1 << i for i in range(8)]], axis=1)))
        self._n_open = ALL_VALVES.sum(axis=1)
        self._gyro = deque(maxlen=max(1, p.gyro_avg))

    def desired_velocity(self, r_hill_m) -> tuple[np.ndarray, str]:
        p = self.params
        e = np.asarray(r_hill_m, float) - self.dock_hill_m
        d = -float(e @ APPROACH_AXIS_HILL)
        e_lat = e + d * APPROACH_AXIS_HILL
        lat = np.linalg.norm(e_lat)
        v_lat = -p.k_lat_ps * e_lat
        s = np.linalg.norm(v_lat)
        if s > p.v_lat_max_mps:
            v_lat *= p.v_lat_max_mps / s
        if lat <= max(p.lat_tol_m, p.cone * max(d, 0.0)):
            v_ax = float(np.clip(p.k_ax_ps * d, p.v_min_mps, p.v_max_mps))
            behaviour = "approach"
        else:
            v_ax = 0.0
            behaviour = "align"
        return v_lat + v_ax * APPROACH_AXIS_HILL, behaviour

    def step(self, r_hill_m, v_hill_mps, q_hb, gyro_bi_b_rps) -> ControlDecision:
        p = self.params
        self._gyro.append(np.asarray(gyro_bi_b_rps, float))
        w_meas = np.mean(self._gyro, axis=0)
        v_des, behaviour = self.desired_velocity(r_hill_m)
        c_bh = rotmat(q_hb).T
        dv_des = c_bh @ (v_des - np.asarray(v_hill_mps, float)) * min(1.0, p.dt_s / p.tau_v_s)
        w_bh = -p.k_att_ps * boxminus(q_hb, self.q_des_hb)
        s = np.linalg.norm(w_bh)
        if s > p.w_bh_max_rps:
            w_bh *= p.w_bh_max_rps / s
        w_des = w_bh + c_bh @ np.array([0.0, 0.0, p.n_radps])
        dw_des = (w_des - w_meas) * min(1.0, p.dt_s / p.tau_w_s)
        cost = (
            np.sum(((dv_des - self._dv) / self._dv1) ** 2, axis=1)
            + p.w_rot * np.sum(((dw_des - self._dw) / self._dw1) ** 2, axis=1)
            + p.w_fuel * self._n_open
        )
        k = int(np.argmin(cost))
        return ControlDecision(k, ALL_VALVES[k].copy(), v_des, w_des, behaviour)
