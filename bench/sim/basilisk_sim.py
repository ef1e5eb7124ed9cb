"""Flight logs (format version 2) from Basilisk, the AVS Lab's astrodynamics
framework (PyPI ``bsk``, the optional extra ``pip install .[basilisk]``): a
second truth engine beside bench/sim/vehicle_sim.py, written elsewhere, so a
mistake the bench's plant shares with the diagnosis shows up beside it.

    log, key = simulate(description, plan, effects, seed, clocks)

The same call as ``bench.sim.vehicle_sim.simulate``, flown by Basilisk:

- two spacecraft in a real Earth orbit, the host (a point mass) and the
  inspector (hub, thrusters, IMU), both under Basilisk's gravity; the
  relative state is converted into the host's Hill frame (x radial, z orbit
  normal, turning at |h| / |r|^2) at every IMU tick. Both fly rather than the
  inspector alone against an analytic host orbit so that J2 and drag act on
  the host through the same modules as on the inspector;
- the inspector's body frame B is the description's structural frame: the
  hub's centre of mass sits at ``com_b_m`` (plus a centre-of-mass offset),
  the thrusters (thrusterDynamicEffector) and the IMU (imuSensor) at their
  described positions in B;
- the valves are replayed from the plan's commands. Every switching instant
  is commanded explicitly (on: the time to the thruster's next switch plus a
  margin; off: zero), because the effector's own on-time countdown leaks one
  Runge-Kutta stage past the pulse's end (docs/BASILISK.md);
- the IMU samples are Basilisk's imuSensor run at every integration step,
  its delta-v and delta-angle outputs summed over each log interval
  (interval mean, as the log format states); the white noise of the
  description is added per log sample here, so that it has the described
  sigma whatever the step;
- the pose sensor is the bench's (Basilisk has none): the described
  reference point's Hill position and the attitude, from Basilisk's truth,
  with the bench's noise.

Time: Basilisk steps at ``STEP_S`` (1 ms); valve switches, IMU stamps and
pose captures are put on that grid (a jittered stamp moves by at most half a
step). Effects: ``EFFECTS_HERE`` (docs/BASILISK.md maps each to its module).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

from bench.sim.flight_log import FlightLog
from bench.sim.log_description import resolve
from bench.sim.vehicle_sim import KNOWN, POSE_ATT_SIGMA_RAD, POSE_POS_FRAC, Clocks, sample_imu
from bench.so3 import qexp, qlog, qmul, qnormalize, quat_from_rotmat, rotmat

STEP_S = 1e-3
J2_INCLINATION_RAD = np.deg2rad(51.6)  # as the bench's differential J2 (bench/sim/plant.py)
AIR_DENSITY_KGPM3 = 5e-13  # as the bench's differential drag
SLOSH_FREQ_HZ, SLOSH_DAMPING = 0.3, 0.05  # as the bench's fuel slosh
PANEL_MASS_FRACTION, PANEL_ARM_M = 0.02, 0.15  # the hinged panel (out of library): 2 % of the mass, 15 cm arm
PANEL_DAMPING = 0.005  # the panel mode's damping ratio, as the bench's flexible mode
EFFECTS_HERE = KNOWN  # the bench plant's effects (bench/sim/vehicle_sim.py), each by Basilisk's modules


def basilisk_version() -> str:
    import importlib.metadata

    return importlib.metadata.version("bsk")


def _require_basilisk():
    try:
        import Basilisk  # noqa: F401
    except ImportError as exc:
        raise ValueError(
            f"the Basilisk engine needs the optional extra: pip install '.[basilisk]' (PyPI bsk; {exc})"
        ) from None


# --- frames -------------------------------------------------------------------


def mrp_to_dcm_bn(sigma) -> np.ndarray:
    """(N, 3) MRPs sigma_BN -> (N, 3, 3) [BN] (N components -> B components)."""
    return np.transpose(Rotation.from_mrp(np.atleast_2d(np.asarray(sigma, float))).as_matrix(), (0, 2, 1))


def dcm_to_mrp(c_bn: np.ndarray) -> np.ndarray:
    """[BN] -> sigma_BN, |sigma| <= 1."""
    return Rotation.from_matrix(np.asarray(c_bn, float).T).as_mrp()


def hill_frame(r_c, v_c):
    """(C_HN (N,3,3), theta_dot (N,)) of the host's Hill frame."""
    r_c, v_c = np.atleast_2d(r_c), np.atleast_2d(v_c)
    h = np.cross(r_c, v_c)
    x = r_c / np.linalg.norm(r_c, axis=1)[:, None]
    z = h / np.linalg.norm(h, axis=1)[:, None]
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1), np.linalg.norm(h, axis=1) / np.sum(r_c * r_c, axis=1)


def relative_hill(r_c, v_c, r_d, v_d):
    """Deputy relative to the host in the host's Hill frame: (r, v, C_HN).
    The frame's rate is taken as |h| / |r|^2 about z (exact on a Kepler
    orbit; J2's out-of-plane turn, ~1e-6 rad/s, is left out)."""
    c_hn, thd = hill_frame(r_c, v_c)
    dr = np.einsum("nij,nj->ni", c_hn, r_d - r_c)
    dv = np.einsum("nij,nj->ni", c_hn, v_d - v_c)
    w = np.zeros_like(dr)
    w[:, 2] = thd
    return dr, dv - np.cross(w, dr), c_hn


def imu_dv_error(accum_dv_b, sigma_bn) -> np.ndarray:
    """(N, 3) what imuSensor adds to each step's delta-v (body axes) beyond the
    true one. It turns the spacecraft's body-frame running total A of delta-v
    (a sum of increments each in its own step's body axes) into inertial axes
    with the attitude of the step's end and of its start, and differences:
    C_NB2 A2 - C_NB1 A1 = C_NB2 dA + (C_NB2 - C_NB1) A1. The second term,
    about (omega x A1) dt, is not a delta-v: it grows with all the delta-v
    since the start (docs/BASILISK.md). In step-end body axes it is
    A1 - C_B2N C_NB1 A1."""
    a = np.asarray(accum_dv_b, float)
    c_bn = mrp_to_dcm_bn(sigma_bn)
    err = np.zeros_like(a)
    err[1:] = a[:-1] - np.einsum("nij,njk,nk->ni", c_bn[1:], np.transpose(c_bn[:-1], (0, 2, 1)), a[:-1])
    return err


# --- the hinged panel ------------------------------------------------------------


class PanelLayout(NamedTuple):
    mass_kg: float
    arm_m: float  # hinge to the panel's centre of mass, along -x
    inertia_s: np.ndarray  # about the panel's centre of mass, panel axes (arm, hinge, normal)
    hinge_b_m: np.ndarray
    hub_mass_kg: float
    hub_com_b_m: np.ndarray
    hub_inertia: np.ndarray  # about the hub's centre of mass
    stiffness: float  # N m / rad
    damping: float  # N m s / rad
    theta0_rad: float  # the hinge angle the run starts at
    coupled_freq_hz: float


def _planar_mode(
    hub_kg: float, hub_jz: float, arm_hub_m: float, panel_kg: float, panel_jz: float, arm_m: float, k: float
):
    """The panel's mode with the hub free in the plane of the hinge: (omega^2,
    hub angle / hinge angle). Coordinates: the hub's sideways translation,
    its angle, the panel's angle; the hinge sits arm_hub_m behind the hub's
    centre of mass and the panel's centre of mass arm_m behind the hinge."""
    a, d = arm_hub_m, arm_m
    m = np.array(
        [
            [hub_kg + panel_kg, -panel_kg * a, -panel_kg * d],
            [-panel_kg * a, hub_jz + panel_kg * a * a, panel_kg * a * d],
            [-panel_kg * d, panel_kg * a * d, panel_jz + panel_kg * d * d],
        ]
    )
    kk = k * np.array([[0.0, 0.0, 0.0], [0.0, 1.0, -1.0], [0.0, -1.0, 1.0]])
    w2, v = np.linalg.eig(np.linalg.solve(m, kk))
    i = int(np.argmax(w2.real))
    y, phi, psi = v[:, i].real
    return float(w2[i].real), float(phi / (psi - phi))


def panel_layout(
    hub_mass_kg: float, com_b_m, inertia_kgm2, vehicle_mass_kg: float, freq_hz: float, amplitude_rad: float
) -> PanelLayout:
    """The hinged panel of ``flex_mode`` [frequency, amplitude] as a part of
    the described vehicle: ``PANEL_MASS_FRACTION`` of its mass on a
    ``PANEL_ARM_M`` arm from a hinge about body z at the centre of mass. The
    hub (``hub_mass_kg`` with the panel, at ``com_b_m``, ``inertia_kgm2``
    about it) gives the panel its mass and inertia and moves its own centre
    of mass forward, so that hub and panel at rest have the described mass,
    centre of mass and inertia; the panel adds only its flexibility, as the
    bench's mode. The stiffness puts the mode of the panel on the free hub
    (the observed frequency) at ``freq_hz``; the run starts with the panel
    deflected so that the hub swings by ``amplitude_rad``."""
    com = np.asarray(com_b_m, float)
    j = np.asarray(inertia_kgm2, float)
    mp = PANEL_MASS_FRACTION * float(vehicle_mass_kg)
    d = PANEL_ARM_M
    ip = mp * d * d / 3.0  # a uniform rod of length 2d about its middle
    inertia_s = np.diag([ip / 10.0, ip, ip])
    r_s = np.array([-d, 0.0, 0.0])  # the panel's centre of mass from the hinge
    # Panel axes in B: arm along x, hinge along z, normal along -y (the H frame of dcm_HB below).
    c_bs = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    m_hub = float(hub_mass_kg) - mp
    if m_hub <= 0.0:
        raise ValueError(f"flex_mode: the panel ({mp:.3g} kg) is heavier than the hub ({hub_mass_kg:.3g} kg)")
    r_h = -mp * r_s / m_hub  # the hub's centre of mass from the vehicle's: the two balance about it

    def parallel(m, r):
        return m * (r @ r * np.eye(3) - np.outer(r, r))

    j_hub = j - (c_bs @ inertia_s @ c_bs.T + parallel(mp, r_s)) - parallel(m_hub, r_h)
    ev = np.linalg.eigvalsh(j_hub)
    if ev[0] <= 0.0 or 2.0 * ev.max() >= ev.sum():
        raise ValueError(
            f"flex_mode: the vehicle's inertia {np.diag(j).round(4).tolist()} cannot hold the panel "
            f"({mp:.3g} kg on a {d} m arm)"
        )
    w2, phi_per_theta = _planar_mode(
        float(vehicle_mass_kg) - mp, float(j_hub[2, 2]), float(np.linalg.norm(r_h)), mp, ip, d, 1.0
    )
    k = (2.0 * np.pi * float(freq_hz)) ** 2 / w2
    om = 2.0 * np.pi * float(freq_hz)
    return PanelLayout(
        mp,
        d,
        inertia_s,
        com.copy(),
        m_hub,
        com + r_h,
        j_hub,
        k,
        2.0 * PANEL_DAMPING * k / om,
        float(amplitude_rad) / abs(phi_per_theta),
        float(freq_hz),
    )


# --- one run --------------------------------------------------------------------


def _host_orbit(desc, effects: dict, t0: float, mu: float):
    """Host position and velocity (inertial) at the run's start: a circular
    orbit (inclination 51.6 deg, node on x, argument of latitude n t0), or
    the eccentric orbit of ``host_eccentricity`` with the bench's phase."""
    from bench.sim.effects import true_anomaly_after

    a = desc.orbit_radius_m
    n = np.sqrt(mu / a**3)
    inc = J2_INCLINATION_RAD
    if "host_eccentricity" in effects:
        e, f0 = (float(x) for x in np.atleast_1d(effects["host_eccentricity"]))
        f = true_anomaly_after(e, f0, n * t0)
        u = f - f0  # argument of latitude 0 at t = 0, as the bench's Hill axes
        p = a * (1.0 - e * e)
        r = p / (1.0 + e * np.cos(f))
        vr, vt = np.sqrt(mu / p) * e * np.sin(f), np.sqrt(mu / p) * (1.0 + e * np.cos(f))
    else:
        u, r, vr, vt = n * t0, a, 0.0, np.sqrt(mu / a)
    xh = np.array([np.cos(u), np.cos(inc) * np.sin(u), np.sin(inc) * np.sin(u)])
    zh = np.array([0.0, -np.sin(inc), np.cos(inc)])
    yh = np.cross(zh, xh)
    return r * xh, vr * xh + vt * yh


def _valve_events(seg, k: int, h: float):
    """Switching instants on the step grid (integer steps) and the valve
    states from each: [(step, on (K,) bool, steps to each thruster's next switch)]."""
    t_cmd = np.asarray(seg.cmd_t_s, float)
    on = np.asarray(seg.cmd_on_s, float).reshape(-1, k)
    pulses = [[] for _ in range(k)]
    for tc, row in zip(t_cmd, on):
        for i in range(k):
            if row[i] > 0.0:
                a, b = int(round(tc / h)), int(round((tc + row[i]) / h))
                if b > a:
                    pulses[i].append((a, b))
    steps = sorted({s for p in pulses for ab in p for s in ab})
    events = []
    for s in steps:
        state = np.zeros(k, bool)
        nxt = np.zeros(k)
        for i in range(k):
            for a, b in pulses[i]:
                if a <= s < b:
                    state[i] = True
                    nxt[i] = b - s
        events.append((s, state, nxt))
    return events


def _add_inspector(sim, desc, effects: dict, duration_s: float):
    """The inspector in ``sim``'s task "step": its hub, thrusters and the
    effects' state effectors (fuel tank, slosh, hinged panel). Returns
    (spacecraft, thrusters, their command message, the centre of mass in B,
    the Basilisk objects that must outlive the run)."""
    from Basilisk.simulation import spacecraft

    com = np.asarray(desc.com_b_m, float) + np.asarray(effects.get("com_offset", np.zeros(3)), float)
    mdot = float(np.atleast_1d(effects.get("mass_depletion", [0.0]))[0])
    slosh_m = float(np.atleast_1d(effects.get("fuel_slosh", [0.0]))[0])
    flex = np.atleast_1d(effects.get("flex_mode", [0.0, 0.0])).astype(float)
    insp = spacecraft.Spacecraft()
    insp.ModelTag = "inspector"
    m_total = float(desc.mass_kg)
    m_hub = m_total - slosh_m
    j_hub = np.asarray(desc.inertia_kgm2, float)
    insp.hub.r_BcB_B = com.reshape(3, 1).tolist()
    insp.hub.IHubPntBc_B = j_hub.tolist()
    thr, cmd, keep = _add_thrusters(insp, desc, effects, mdot)  # Basilisk objects must outlive the run
    if mdot > 0.0:
        m_hub -= _add_fuel_tank(sim, insp, thr, com, m_hub, mdot * desc.n_thrusters, duration_s, keep)
    if slosh_m > 0.0:
        _add_slosh(sim, insp, com, slosh_m, keep)
    if flex[1] != 0.0:
        # The panel is part of the described vehicle: the hub is what is left
        # of its mass, centre of mass and inertia (panel_layout).
        lay = panel_layout(m_hub, com, j_hub, m_total, flex[0], flex[1])
        _add_panel(sim, insp, lay, keep)
        m_hub, j_hub = lay.hub_mass_kg, lay.hub_inertia
        insp.hub.r_BcB_B = lay.hub_com_b_m.reshape(3, 1).tolist()
        insp.hub.IHubPntBc_B = j_hub.tolist()
    insp.hub.mHub = m_hub
    return insp, thr, cmd, com, keep


def _add_thrusters(insp, desc, effects: dict, mdot: float) -> tuple:
    """(thruster effector, its command message, objects to keep): the
    described valves with the thrust effects (loss, tilt, flow per valve)."""
    from Basilisk.architecture import messaging
    from Basilisk.simulation import thrusterDynamicEffector

    k = desc.n_thrusters
    veh = desc.vehicle()  # positions relative to the described centre of mass
    thr = thrusterDynamicEffector.ThrusterDynamicEffector()
    thr.ModelTag = "thrusters"
    pos_b = np.asarray(veh.positions_b_m, float) + np.asarray(desc.com_b_m, float)  # back into B
    dirs = np.asarray(veh.directions_b, float)
    scale = np.ones(k)
    if "thrust_loss" in effects:
        p = np.atleast_1d(np.asarray(effects["thrust_loss"], float))
        scale = 1.0 - (np.full(k, p[0]) if p.size == 1 else p.reshape(k))
    if "thruster_misalignment" in effects:
        phi = np.asarray(effects["thruster_misalignment"], float).reshape(k, 3)
        dirs = np.array([rotmat(qexp(phi[i])) @ dirs[i] for i in range(k)])
    thrust = (
        np.asarray(veh.thrust_n, float) * np.asarray(veh.thrust_scale, float)
        if np.ndim(veh.thrust_n)
        else np.full(k, float(veh.thrust_n)) * np.asarray(veh.thrust_scale, float)
    )
    keep = []
    for i in range(k):
        c = thrusterDynamicEffector.THRSimConfig()
        c.thrLoc_B = pos_b[i].tolist()
        c.thrDir_B = (dirs[i] / np.linalg.norm(dirs[i])).tolist()
        c.MaxThrust = float(thrust[i] * scale[i])
        c.MinOnTime = 0.0
        # mdot = F / (g0 Isp): the bench's flow per open valve.
        c.steadyIsp = float(thrust[i] * scale[i] / (9.80665 * mdot)) if mdot > 0.0 else 0.0
        thr.addThruster(c)
        keep.append(c)
    cmd = messaging.THRArrayOnTimeCmdMsg()
    thr.cmdsInMsg.subscribeTo(cmd)
    insp.addDynamicEffector(thr)
    return thr, cmd, keep


def _add_fuel_tank(sim, insp, thr, com, m_hub: float, mdot_all: float, duration_s: float, keep: list) -> float:
    """All the propellant the run can use, in a tank at the centre of mass
    (a point: the bench's inertia stays fixed as mass is used). Returns the
    propellant's mass, which the hub no longer carries."""
    from Basilisk.simulation import fuelTank

    fuel = min(0.2 * m_hub, 2.0 * mdot_all * duration_s + 1e-3)
    tank = fuelTank.FuelTank()
    model = fuelTank.FuelTankModelConstantVolume()
    model.propMassInit = fuel
    model.r_TcT_TInit = [[0.0], [0.0], [0.0]]
    model.radiusTankInit = 1e-4
    tank.setTankModel(model)
    tank.setR_TB_B(com.reshape(3, 1).tolist())
    tank.addThrusterSet(thr)
    insp.addStateEffector(tank)
    sim.AddModelToTask("step", tank, 95)
    keep += [tank, model]
    return fuel


def _add_slosh(sim, insp, com, slosh_m: float, keep: list) -> None:
    """One spring per body axis through the centre of mass, a third of the
    slosh mass each (the bench's slosh is one mass on an isotropic spring)."""
    from Basilisk.simulation import linearSpringMassDamper

    ws = 2.0 * np.pi * SLOSH_FREQ_HZ
    for ax in range(3):
        p = linearSpringMassDamper.LinearSpringMassDamper()
        p.massInit = slosh_m / 3.0
        p.k = slosh_m / 3.0 * ws**2
        p.c = 2.0 * SLOSH_DAMPING * ws * slosh_m / 3.0
        p.r_PB_B = com.reshape(3, 1).tolist()
        e = np.zeros((3, 1))
        e[ax] = 1.0
        p.pHat_B = e.tolist()
        p.rhoInit, p.rhoDotInit = 0.0, 0.0
        p.nameOfMassState = f"sloshMass{ax}"
        p.nameOfRhoState = f"sloshRho{ax}"
        p.nameOfRhoDotState = f"sloshRhoDot{ax}"
        insp.addStateEffector(p)
        sim.AddModelToTask("step", p, 95)
        keep.append(p)


def _add_panel(sim, insp, lay: PanelLayout, keep: list) -> None:
    """The hinged panel of ``lay`` on the hub."""
    from Basilisk.simulation import hingedRigidBodyStateEffector

    panel = hingedRigidBodyStateEffector.HingedRigidBodyStateEffector()
    panel.mass, panel.d, panel.k, panel.c = lay.mass_kg, lay.arm_m, lay.stiffness, lay.damping
    panel.IPntS_S = lay.inertia_s.tolist()
    panel.r_HB_B = lay.hinge_b_m.reshape(3, 1).tolist()
    # Hinge axis (the H frame's y) along body z: the panel swings in the body x-y plane, its arm along -x.
    panel.dcm_HB = [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]
    panel.thetaInit = lay.theta0_rad
    panel.thetaDotInit = 0.0
    panel.nameOfThetaState = "panelTheta"
    panel.nameOfThetaDotState = "panelThetaDot"
    insp.addStateEffector(panel)
    sim.AddModelToTask("step", panel, 95)
    keep.append(panel)


def flown_mass_properties(description: dict, effects: dict | None = None) -> dict:
    """The inspector's mass properties as Basilisk assembles them from the
    hub and the effects' bodies at the start of a run: mass, centre of mass
    in B and inertia about it (to check against the description)."""
    _require_basilisk()
    from Basilisk.utilities import SimulationBaseClass

    desc = resolve(description)
    sim = SimulationBaseClass.SimBaseClass()
    proc = sim.CreateNewProcess("dynamics")
    step_ns = int(round(STEP_S * 1e9))
    proc.addTask(sim.CreateNewTask("step", step_ns))
    insp, thr, _cmd, _com, _keep = _add_inspector(sim, desc, dict(effects or {}), 1.0)
    sim.AddModelToTask("step", thr, 100)
    sim.AddModelToTask("step", insp, 90)
    rec = insp.scMassOutMsg.recorder()
    sim.AddModelToTask("step", rec, 10)
    sim.InitializeSimulation()
    sim.ConfigureStopTime(0)
    sim.ExecuteSimulation()
    m = float(np.asarray(rec.massSC)[0])
    c = np.asarray(rec.c_B, float)[0]
    i_b = np.asarray(rec.ISC_PntB_B, float)[0].reshape(3, 3)
    return {"mass_kg": m, "com_b_m": c, "inertia_kgm2": i_b - m * (c @ c * np.eye(3) - np.outer(c, c))}


def _fly_segment(seg, t0: float, desc, effects: dict, T: float, imu_t, pose_cap, h: float):
    """Fly one run in Basilisk. ``imu_t``, ``pose_cap`` are step indices from
    the run's start. Returns the IMU's summed outputs per log sample (mean
    specific force, mean rate; IMU axes, without noise) and the truth at the
    IMU ticks and pose captures."""
    from Basilisk.simulation import spacecraft
    from Basilisk.utilities import SimulationBaseClass

    sim = SimulationBaseClass.SimBaseClass()
    sim.SetProgressBar(False) if hasattr(sim, "SetProgressBar") else None
    proc = sim.CreateNewProcess("dynamics")
    step_ns = int(round(h * 1e9))
    proc.addTask(sim.CreateNewTask("step", step_ns))
    grav, earth = _gravity(effects)

    host = spacecraft.Spacecraft()
    host.ModelTag = "host"
    host.hub.mHub = 100.0
    host.hub.IHubPntBc_B = np.eye(3).tolist()
    grav.addBodiesTo(host)

    insp, thr, cmd, com, keep = _add_inspector(sim, desc, effects, seg.duration_s)
    grav.addBodiesTo(insp)
    if "differential_drag" in effects:
        _add_drag(sim, effects, host, insp, com, float(desc.mass_kg), earth.radEquator, keep)
    imu, c_ib = _add_imu(insp, desc, effects)
    _initial_states(host, insp, seg, desc, effects, t0, earth.mu)

    sim.AddModelToTask("step", thr, 100)  # reads its command before the spacecraft integrates the step
    sim.AddModelToTask("step", host, 90)
    sim.AddModelToTask("step", insp, 90)
    sim.AddModelToTask("step", imu, 50)
    rec_imu = imu.sensorOutMsg.recorder()
    rec_ins = insp.scStateOutMsg.recorder()
    rec_host = host.scStateOutMsg.recorder()
    for r in (rec_imu, rec_ins, rec_host):
        sim.AddModelToTask("step", r, 10)
    sim.InitializeSimulation()
    n_steps = _fly_valves(sim, seg, desc.n_thrusters, h, step_ns, cmd)

    steps = np.rint(rec_imu.times() / step_ns).astype(np.int64)
    if steps.size != n_steps + 1 or np.any(steps != np.arange(n_steps + 1)):
        raise RuntimeError("Basilisk recorded an unexpected step sequence")
    f_mean, w_mean = _imu_means(rec_imu, rec_ins, c_ib, imu_t, T, h)
    return (f_mean, w_mean, _truth(rec_host, rec_ins, imu_t), _truth(rec_host, rec_ins, pose_cap), com)


def _gravity(effects: dict) -> tuple:
    """(gravity factory, Earth): a point mass, or with J2 by spherical
    harmonics for differential J2."""
    from Basilisk.utilities import simIncludeGravBody

    grav = simIncludeGravBody.gravBodyFactory()
    earth = grav.createEarth()
    earth.isCentralBody = True
    if "differential_j2" in effects:
        from Basilisk.simulation.sphericalHarmonicsGravityModel import SphericalHarmonicsGravityModel

        j2 = float(np.atleast_1d(effects["differential_j2"])[0])
        sh = SphericalHarmonicsGravityModel()
        sh.muBody, sh.radEquator, sh.maxDeg = earth.mu, earth.radEquator, 2
        # Fully normalised C20 = -J2 / sqrt(5); all else zero.
        sh.cBar = [[1.0], [0.0, 0.0], [-j2 / np.sqrt(5.0), 0.0, 0.0]]
        sh.sBar = [[0.0], [0.0, 0.0], [0.0, 0.0, 0.0]]
        earth.gravityModel = sh
    return grav, earth


def _add_drag(sim, effects: dict, host, insp, com, m_total: float, planet_radius_m: float, keep: list) -> None:
    """Drag on the host and the inspector in a constant-density atmosphere,
    their ballistic coefficients from the differential drag's parameters."""
    from Basilisk.simulation import dragDynamicEffector, exponentialAtmosphere

    p = np.atleast_1d(np.asarray(effects["differential_drag"], float))
    b_host = float(p[1]) if p.size > 1 else max(0.0, -float(p[0]))
    b_insp = float(p[0]) + b_host
    atmo = exponentialAtmosphere.ExponentialAtmosphere()
    atmo.ModelTag = "atmosphere"
    atmo.planetRadius = planet_radius_m
    atmo.baseDensity = AIR_DENSITY_KGPM3
    atmo.scaleHeight = 1e15  # the bench's constant density
    sim.AddModelToTask("step", atmo, 99)
    keep.append(atmo)
    for sc, b, m in ((host, b_host, host.hub.mHub), (insp, b_insp, m_total)):
        if b <= 0.0:
            continue
        atmo.addSpacecraftToModel(sc.scStateOutMsg)
        drag = dragDynamicEffector.DragDynamicEffector()
        drag.coreParams.dragCoeff = 2.0
        drag.coreParams.projectedArea = b * m / 2.0  # B = C_d A / m
        # Basilisk applies the force about the body origin B; the bench's drag acts through the centre of mass.
        drag.coreParams.comOffset = (com if sc is insp else np.zeros(3)).tolist()
        drag.atmoDensInMsg.subscribeTo(atmo.envOutMsgs[-1])
        sc.addDynamicEffector(drag)
        sim.AddModelToTask("step", drag, 98)
        keep.append(drag)


def _add_imu(insp, desc, effects: dict) -> tuple:
    """(Basilisk's IMU on the inspector, its body-to-IMU rotation) with the
    IMU effects (misalignment, biases, scale)."""
    from Basilisk.simulation import imuSensor

    imu = imuSensor.ImuSensor()
    imu.ModelTag = "imu"
    imu.scStateInMsg.subscribeTo(insp.scStateOutMsg)
    imu.sensorPos_B = np.asarray(desc.imu_position_b_m, float).tolist()
    c_ib = rotmat(desc.imu_q_body_imu).T
    if "imu_misalignment" in effects:
        c_ib = rotmat(qexp(effects["imu_misalignment"])).T @ c_ib
    imu.dcm_PB = c_ib.tolist()
    imu.senTransBias = np.asarray(effects.get("accel_bias", np.zeros(3)), float).tolist()
    imu.senRotBias = np.asarray(effects.get("gyro_bias", np.zeros(3)), float).tolist()
    if "gyro_scale" in effects:
        imu.gyroScale = (1.0 + np.asarray(effects["gyro_scale"], float)).tolist()  # per IMU axis, as the library's
    return imu, c_ib


def _initial_states(host, insp, seg, desc, effects: dict, t0: float, mu: float) -> None:
    """The run starts at rest in the Hill frame of the host's orbit."""
    r_c, v_c = _host_orbit(desc, effects, t0, mu)
    c_hn, thd = hill_frame(r_c, v_c)
    c_nh = c_hn[0].T
    r0 = np.asarray(seg.r0_hill_m, float)
    v0 = np.asarray(seg.v0_hill_mps, float)
    w_hn = np.array([0.0, 0.0, thd[0]])
    q0 = qnormalize(np.asarray(seg.q0_hb, float))
    c_hb = rotmat(q0)
    host.hub.r_CN_NInit = r_c.reshape(3, 1).tolist()
    host.hub.v_CN_NInit = v_c.reshape(3, 1).tolist()
    insp.hub.r_CN_NInit = (r_c + c_nh @ r0).reshape(3, 1).tolist()
    insp.hub.v_CN_NInit = (v_c + c_nh @ (v0 + np.cross(w_hn, r0))).reshape(3, 1).tolist()
    insp.hub.sigma_BNInit = dcm_to_mrp((c_nh @ c_hb).T).reshape(3, 1).tolist()
    insp.hub.omega_BN_BInit = (c_hb.T @ w_hn).reshape(3, 1).tolist()


def _fly_valves(sim, seg, k: int, h: float, step_ns: int, cmd) -> int:
    """Run the simulation through the segment, writing each valve switch's
    on-times when it happens. Returns the number of steps flown."""
    from Basilisk.architecture import messaging

    n_steps = int(round(seg.duration_s / h))
    payload = messaging.THRArrayOnTimeCmdMsgPayload()
    for s, state, nxt in _valve_events(seg, k, h):
        if s > n_steps:
            break
        sim.ConfigureStopTime(s * step_ns)
        sim.ExecuteSimulation()
        # On: until the next switch and a step beyond it (the switch itself turns it off).
        payload.OnTimeRequest = [float((nxt[i] + 1) * h) if state[i] else 0.0 for i in range(k)]
        cmd.write(payload, s * step_ns)
    sim.ConfigureStopTime(n_steps * step_ns)
    sim.ExecuteSimulation()
    return n_steps


def _imu_means(rec_imu, rec_ins, c_ib, imu_t, T: float, h: float) -> tuple:
    """(mean specific force, mean rate) over each log sample's interval, in
    IMU axes, from Basilisk's per-step delta-v and delta-angle."""
    dv = np.asarray(rec_imu.DVFramePlatform, float)
    dv = dv - imu_dv_error(np.asarray(rec_ins.TotalAccumDV_BN_B, float), np.asarray(rec_ins.sigma_BN, float)) @ c_ib.T
    dr = np.asarray(rec_imu.DRFramePlatform, float)
    cum_dv = np.cumsum(dv, axis=0)
    i1 = np.asarray(imu_t, np.int64)
    i0 = i1 - int(round(T / h))
    f_mean = (cum_dv[i1] - cum_dv[i0]) / T
    w_mean = np.zeros((i1.size, 3))
    for j, (a, b) in enumerate(zip(i0, i1)):
        q = np.array([1.0, 0.0, 0.0, 0.0])
        for p in dr[a + 1 : b + 1]:
            q = qmul(q, qexp(p))
        w_mean[j] = qlog(q) / T
    return f_mean, w_mean


def _truth(rec_host, rec_ins, idx) -> tuple:
    """(r, v, q, w, body origin) in the Hill frame at the recorded steps ``idx``."""
    idx = np.asarray(idx, np.int64)
    rc, vc = np.asarray(rec_host.r_CN_N)[idx], np.asarray(rec_host.v_CN_N)[idx]
    rd, vd = np.asarray(rec_ins.r_CN_N)[idx], np.asarray(rec_ins.v_CN_N)[idx]
    rb = np.asarray(rec_ins.r_BN_N)[idx]
    r, v, c_hn = relative_hill(rc, vc, rd, vd)
    rb_h = np.einsum("nij,nj->ni", c_hn, rb - rc)
    c_bn = mrp_to_dcm_bn(np.asarray(rec_ins.sigma_BN)[idx])
    q = quat_from_rotmat(c_hn @ np.transpose(c_bn, (0, 2, 1)))
    w = np.asarray(rec_ins.omega_BN_B)[idx]
    return r, v, q, w, rb_h


# --- the log ----------------------------------------------------------------------


def simulate(
    description: dict,
    plan: list,
    effects: dict | None = None,
    seed: int = 0,
    clocks: Clocks | None = None,
    with_truth: bool = True,
    noise: bool = True,
) -> tuple:
    """(FlightLog, key) of ``plan`` flown in Basilisk by the described vehicle
    with ``effects`` (``noise=False``: the sensors without white noise)."""
    _require_basilisk()
    effects = dict(effects or {})
    unknown = sorted(set(effects) - set(EFFECTS_HERE))
    if unknown:
        raise ValueError(
            f"effect {unknown[0]!r} not simulated by the Basilisk engine (known: {', '.join(EFFECTS_HERE)})"
        )
    clocks = clocks or Clocks()
    desc = resolve(description)
    rng = np.random.default_rng(seed)
    h = STEP_S
    T = 1.0 / (desc.imu_rate_hz or 10.0)
    if abs(T / h - round(T / h)) > 1e-9:
        raise ValueError(f"the IMU interval {T} s is not a whole number of Basilisk steps ({h} s)")
    latency = float(np.atleast_1d(effects.get("camera_latency", 0.0))[0])
    out = {
        k: [] for k in ("imu_t", "acc", "gyr", "pc", "pd", "pr", "pq", "prs", "vt", "von", "tt", "tr", "tv", "tq", "tw")
    }
    segments = []
    t0 = 0.0
    for seg in plan:
        imu_i, pose_i, cap_i = _sample_steps(seg, clocks, rng, T, h, latency)
        f_mean, w_mean, tr_imu, tr_pose, _ = _fly_segment(seg, t0, desc, effects, T, imu_i, cap_i, h)
        s_a = desc.accel_sigma_mps2 if noise else 0.0
        s_g = desc.gyro_sigma_rps if noise else 0.0
        imu_t = t0 + imu_i * h
        sample_imu(out, rng, clocks, imu_t, f_mean, w_mean, s_a, s_g)
        _measure_poses(out, desc, effects, clocks, rng, noise, tr_pose, t0 + pose_i * h)
        out["vt"].append(t0 + np.asarray(seg.cmd_t_s, float))
        out["von"].append(np.asarray(seg.cmd_on_s, float).reshape(-1, desc.n_thrusters))
        r, v, q, w, _ = tr_imu
        out["tt"].append(imu_t)
        out["tr"].append(r)
        out["tv"].append(v)
        out["tq"].append(q)
        out["tw"].append(w)
        segments.append(
            {
                "t_start_s": float(t0),
                "t_end_s": float(t0 + seg.duration_s),
                "manoeuvre": seg.manoeuvre,
                "starts_at_rest": bool(np.all(np.asarray(seg.v0_hill_mps) == 0.0)),
            }
        )
        t0 += seg.duration_s + clocks.gap_s
    for sg in segments:  # stamps written on the clocks' epoch (the flight simulated from zero)
        sg["t_start_s"] += clocks.epoch_s
        sg["t_end_s"] += clocks.epoch_s
    log = _log_of(out, description, segments, seed, h, with_truth, clocks.epoch_s)
    key = {
        "seed": int(seed),
        "engine": "basilisk",
        "effects": {k: np.asarray(v, float).ravel().tolist() for k, v in effects.items()},
    }
    return log, key


def _sample_steps(seg, clocks: Clocks, rng, T: float, h: float, latency: float) -> tuple:
    """(IMU sample steps, pose delivery steps, pose capture steps) of one
    run, with the clocks' jitter."""
    nT = int(round(T / h))
    n_steps = int(round(seg.duration_s / h))
    nominal = np.arange(nT, n_steps + 1, nT)
    jit = np.clip(clocks.imu_jitter_s * rng.standard_normal(nominal.size), -0.3 * T, 0.3 * T)
    # As the bench: a sample whose interval would start before the run is left out, the last ends at the run's end.
    t_imu = np.minimum(nominal * h + jit, n_steps * h)
    t_imu = t_imu[t_imu - T >= -1e-12]
    imu_i = np.unique(np.clip(np.rint(t_imu / h).astype(np.int64), nT, n_steps))
    n_pose = int(np.floor((seg.duration_s - clocks.pose_phase_s) / clocks.pose_period_s + 1e-9)) + 1
    pose_t = clocks.pose_phase_s + clocks.pose_period_s * np.arange(n_pose)
    pose_t = pose_t + np.clip(clocks.pose_jitter_s * rng.standard_normal(pose_t.size), -0.2, 0.2)
    pose_i = np.rint(pose_t / h).astype(np.int64)
    cap_i = np.rint((pose_t - latency) / h).astype(np.int64)
    ok = (cap_i >= 0) & (pose_i <= n_steps)
    return imu_i, pose_i[ok], cap_i[ok]


def _measure_poses(out: dict, desc, effects: dict, clocks: Clocks, rng, noise: bool, tr_pose, t_pose) -> None:
    """The pose sensor's measurements of the truth at its captures (its
    reference point and lever arm, its noise), stamped as the log states."""
    pref = desc.pose_reference_b_m  # in B: Basilisk knows where B is
    lever = np.asarray(effects.get("camera_lever_arm", np.zeros(3)), float)
    _, _, q_p, _, rb_p = tr_pose
    for j in range(t_pose.size):
        r_meas = rb_p[j] + rotmat(q_p[j]) @ (pref + lever)
        sig = POSE_POS_FRAC * max(np.linalg.norm(r_meas), 0.05) if noise else 0.0
        r_meas = r_meas + sig * rng.standard_normal(3)
        q_meas = qnormalize(qmul(q_p[j], qexp((POSE_ATT_SIGMA_RAD if noise else 0.0) * rng.standard_normal(3))))
        stamp = t_pose[j] - desc.pose_time_offset_s + desc.pose_latency_s
        out["pc"].append(stamp)
        out["pd"].append(stamp + clocks.pose_delay_s)
        out["pr"].append(r_meas)
        out["pq"].append(q_meas)
        out["prs"].append(max(sig, 1e-6))


def _log_of(
    out: dict, description: dict, segments: list, seed: int, h: float, with_truth: bool, epoch_s: float = 0.0
) -> FlightLog:
    """The flight log (format 2) of the collected streams, every time stamp
    written ``epoch_s`` later."""
    cat = {
        k: np.concatenate(v)
        for k, v in out.items()
        if k in ("imu_t", "acc", "gyr", "vt", "von", "tt", "tr", "tv", "tq", "tw")
    }
    for k in ("imu_t", "vt", "tt"):
        cat[k] = cat[k] + epoch_s
    out = dict(out, pc=[x + epoch_s for x in out["pc"]], pd=[x + epoch_s for x in out["pd"]])
    pc = np.asarray(out["pc"], float)
    log_desc = dict(description)
    log_desc["segments"] = segments
    log = FlightLog(
        streams={
            "imu": {"t_s": cat["imu_t"], "accel_b_mps2": cat["acc"], "omega_bi_b_rps": cat["gyr"]},
            "pose": {
                "t_capture_s": pc,
                "t_delivered_s": np.asarray(out["pd"], float),
                "r_hill_m": np.asarray(out["pr"], float).reshape(-1, 3),
                "q_hb": np.asarray(out["pq"], float).reshape(-1, 4),
                "r_sigma_m": np.asarray(out["prs"], float),
                "att_sigma_rad": np.full(pc.size, POSE_ATT_SIGMA_RAD),
            },
            "valves": {"t_s": cat["vt"], "on_time_s": cat["von"]},
        },
        config={
            "source": "proxops basilisk_sim",
            "engine": "basilisk",
            "basilisk_version": basilisk_version(),
            "step_s": h,
            "seed": int(seed),
        },
        description=log_desc,
    )
    if with_truth:
        log.streams["truth"] = {
            "t_s": cat["tt"],
            "r_hill_m": cat["tr"],
            "v_hill_mps": cat["tv"],
            "q_hb": cat["tq"],
            "omega_bi_b_rps": cat["tw"],
        }
    return log
