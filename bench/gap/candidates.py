"""The diagnoser's own parametric model of each in-library effect: a map from
a small parameter vector to corrections of the filter's inputs
(bench/gap/replay.py). These are written independently of the plant's
physics (bench/sim/effects.py): the diagnoser sees an effect only through what
it does to the IMU and pose streams and to the relative dynamics.

Effects that change the thrust or the mass properties (thrust loss,
thruster misalignment, a centre-of-mass offset, mass depletion) leave the
navigation replay untouched: the accelerometer and gyro measure what the
vehicle really did, and the replay navigates the IMU's own point, which a
pose reference point fixed in the body follows whatever the mass does. They
are seen through the dynamics channel (bench/gap/dyn.py), which models them
and the IMU's own errors exactly (``nav=False``: dynamics channel only). A drifting flight
clock (``clock_drift``) rescales every time tag of the log in the replay
and every interval of the dynamics channel. The flexible mode has no
candidate yet (``NOT_MODELLED``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from bench.gap.load import LogData
from bench.gap.replay import Corrections


@dataclass(frozen=True)
class Candidate:
    name: str
    kind: str  # "sensor" | "dynamics"
    params: tuple  # parameter names, with units
    scale: float  # a typical size, for finite differences and the optimiser's scaling
    separate_by: str  # the manoeuvre that tells it apart from look-alikes
    bound: float = float("inf")  # physically plausible |parameter| (fits are kept inside)
    nav: bool = True  # has a signature in the navigation replay (else only in the dynamics channel)
    # A quantity that has a sign by its definition (a loss of thrust, a flow of
    # propellant out of the tank) is fitted in [0, bound], not [-bound, bound].
    nonnegative: bool = False

    @property
    def n_params(self) -> int:
        return len(self.params)

    @property
    def lower(self) -> float:
        return 0.0 if self.nonnegative else -self.bound

    def corrections(self, theta, d: LogData) -> Corrections:
        if not self.nav:
            return Corrections()
        return _BUILDERS[self.name](np.asarray(theta, float), d)


def _zero3():
    return np.zeros(3)


def _t(d: LogData) -> np.ndarray:
    return d.imu_t - d.t_init


def _ecc(theta, d: LogData) -> Corrections:
    # First order in e of the relative motion about an elliptical host orbit,
    # minus the circular CW model: M = M0 + n t, theta = [e cos M0, e sin M0].
    n = d.n_radps
    nt = n * _t(d)
    ec = theta[0] * np.cos(nt) - theta[1] * np.sin(nt)  # e cos M
    es = theta[1] * np.cos(nt) + theta[0] * np.sin(nt)  # e sin M
    r, v = d.ref_r, d.ref_v
    a = np.empty_like(r)
    a[:, 0] = 4 * n * ec * v[:, 1] - 2 * n * n * es * r[:, 1] + 10 * n * n * ec * r[:, 0]
    a[:, 1] = -4 * n * ec * v[:, 0] + 2 * n * n * es * r[:, 0] + n * n * ec * r[:, 1]
    a[:, 2] = -3 * n * n * ec * r[:, 2]
    return Corrections(hill_accel=a)


def _j2(theta, d: LogData) -> Corrections:
    # Differential J2 over a short arc: a gravity-gradient-like symmetric,
    # trace-free matrix K (5 parameters, [1/s^2]) acting on the position.
    k = np.array(
        [[theta[0], theta[2], theta[3]], [theta[2], theta[1], theta[4]], [theta[3], theta[4], -theta[0] - theta[1]]]
    )
    return Corrections(hill_accel=d.ref_r @ k.T)


def _drag(theta, d: LogData) -> Corrections:
    # Drag: along-track accelerations of the inspector (theta[0]) and of the
    # host (theta[1]) [m/s^2]. The inspector's accelerometer senses its own
    # drag, so the filter already integrates it; the relative motion lacks
    # only the host's, -theta[1]. The inspector's shows in the dynamics
    # channel (bench/gap/dyn.py).
    a = np.zeros((d.imu_t.size, 3))
    a[:, 1] = -theta[1]
    return Corrections(hill_accel=a)


_BUILDERS = {
    "accel_bias": lambda th, d: Corrections(accel_bias=th),
    "gyro_bias": lambda th, d: Corrections(gyro_bias=th),
    "gyro_scale": lambda th, d: Corrections(gyro_scale=th),
    "imu_misalignment": lambda th, d: Corrections(imu_misalign=th),
    "camera_latency": lambda th, d: Corrections(latency_s=float(th[0])),
    "camera_lever_arm": lambda th, d: Corrections(lever_arm_b=th),
    "host_eccentricity": _ecc,
    "differential_j2": _j2,
    "differential_drag": _drag,
    "clock_drift": lambda th, d: Corrections(clock_eps=float(th[0])),
}


def candidates_of(d: LogData) -> dict:
    """The candidate models for the vehicle a prepared log describes."""
    if d.desc is None:
        return CANDIDATES
    return _candidates_cached(int(d.desc.n_thrusters), float(d.desc.envelope_m), float(d.desc.max_mass_flow_kgps))


@lru_cache(maxsize=16)
def _candidates_cached(n_thrusters: int, envelope_m: float, max_mass_flow_kgps: float) -> dict:
    return candidates_for(n_thrusters, envelope_m, max_mass_flow_kgps)


def candidates_for(
    n_thrusters: int = 8, envelope_m: float | None = None, max_mass_flow_kgps: float | None = None
) -> dict:
    """The candidate models for a vehicle with ``n_thrusters`` valves (the
    per-valve effects have one parameter, or three, per valve) whose largest
    dimension is ``envelope_m`` (bounds the camera's lever arm: a camera
    cannot sit farther from the body origin than the vehicle reaches) and
    whose valves expel at most ``max_mass_flow_kgps`` each (bounds the mass
    flow: a fit beyond it is not propellant use but something else)."""
    out = dict(CANDIDATES)
    if n_thrusters != 8:
        k = int(n_thrusters)
        tl, tm = CANDIDATES["thrust_loss"], CANDIDATES["thruster_misalignment"]
        out["thrust_loss"] = replace(tl, params=tuple(f"loss_{i} [1]" for i in range(k)))
        out["thruster_misalignment"] = replace(tm, params=tuple(f"phi_{i}{a} [rad]" for i in range(k) for a in "xyz"))
    if envelope_m is not None and envelope_m > 0.0:
        out["camera_lever_arm"] = replace(CANDIDATES["camera_lever_arm"], bound=float(envelope_m))
    if max_mass_flow_kgps is not None and max_mass_flow_kgps > 0.0:
        md = CANDIDATES["mass_depletion"]
        out["mass_depletion"] = replace(md, bound=float(max_mass_flow_kgps))
    return out


CANDIDATES = {
    c.name: c
    for c in (
        Candidate(
            "thrust_loss",
            "dynamics",
            tuple(f"loss_{i} [1]" for i in range(8)),
            0.1,
            "each valve alone for 3 s, then 20 s without firing, valve by valve (200 s): a loss changes the rate "
            "along the valve's torque, a tilt across it (python -m bench.campaigns.gap.characterise)",
            bound=0.9,
            nav=False,
            nonnegative=True,
        ),
        Candidate(
            "thruster_misalignment",
            "dynamics",
            tuple(f"phi_{i}{a} [rad]" for i in range(8) for a in "xyz"),
            0.05,
            "each valve alone for 3 s, then 20 s without firing, valve by valve (200 s): a tilt changes the rate "
            "across the valve's torque, a loss along it (python -m bench.campaigns.gap.characterise)",
            bound=0.5,
            nav=False,
        ),
        Candidate(
            "mass_depletion",
            "dynamics",
            ("mdot [kg/s per open valve]",),
            1e-3,
            "a long firing: the acceleration per valve grows as propellant is used",
            bound=0.02,
            nav=False,
            nonnegative=True,
        ),
        Candidate(
            "com_offset",
            "dynamics",
            ("c_x [m]", "c_y [m]", "c_z [m]"),
            0.01,
            "fast slews with pure couples: the accelerometer's lever arm reads w x (w x c) and wdot x c",
            bound=0.1,
            nav=False,
        ),
        Candidate(
            "accel_bias",
            "sensor",
            ("b_x [m/s^2]", "b_y [m/s^2]", "b_z [m/s^2]"),
            3e-4,
            "a slew during a coast: a body-fixed bias turns with the body, a Hill-frame acceleration does not",
            bound=1e-2,
        ),
        Candidate(
            "gyro_bias",
            "sensor",
            ("b_x [rad/s]", "b_y [rad/s]", "b_z [rad/s]"),
            1e-3,
            "hold attitude, then slew about each axis at two rates: a bias is rate-independent",
            bound=5e-2,
        ),
        Candidate(
            "gyro_scale",
            "sensor",
            ("s_x [1]", "s_y [1]", "s_z [1]"),
            0.05,
            "slew about each axis at two rates: a scale error grows with the rate",
            bound=0.5,
        ),
        Candidate(
            "imu_misalignment",
            "sensor",
            ("e_x [rad]", "e_y [rad]", "e_z [rad]"),
            0.01,
            "fire single-axis translations and slews: misalignment couples axes",
            bound=0.5,
        ),
        Candidate(
            "camera_latency",
            "sensor",
            ("tau [s]",),
            0.2,
            "fast translation and slew at constant range: latency scales with the speed",
            bound=3.0,
        ),
        Candidate(
            "camera_lever_arm",
            "sensor",
            ("l_x [m]", "l_y [m]", "l_z [m]"),
            0.02,
            "slew at a fixed position: a lever arm moves the measured position with the attitude",
            bound=0.3,
        ),
        Candidate(
            "host_eccentricity",
            "dynamics",
            ("e cos M0 [1]", "e sin M0 [1]"),
            0.02,
            "a long coast at larger radial offset: the terms scale with position and orbit phase",
            bound=0.3,
        ),
        Candidate(
            "differential_j2",
            "dynamics",
            ("K_xx", "K_yy", "K_xy", "K_xz", "K_yz [1/s^2]"),
            1e-5,
            "coasts at offsets along each Hill axis: a gradient scales with the offset",
            bound=1e-3,
        ),
        Candidate(
            "differential_drag",
            "dynamics",
            ("a_inspector_y [m/s^2]", "a_host_y [m/s^2]"),
            1e-4,
            "a coast near the host: drag is constant along-track, independent of position and attitude; "
            "a slew shows the inspector's own drag turning in the accelerometer",
            bound=1e-2,
        ),
        Candidate(
            "clock_drift",
            "sensor",
            ("eps [1]",),
            0.01,
            "slews and firings of known length: a fast clock stretches every interval, so the pose updates "
            "read the rates too large while the gyro against the valve torques reads them too small",
            bound=0.05,
        ),
    )
}

NOT_MODELLED = ("flex_mode",)
