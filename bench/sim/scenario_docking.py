"""The paper's docking scenario: the inspector starts 0.75 m from the host's
centre of mass and docks autonomously, navigating with the flight UKF
(fsw_bindings.NavUkf) from a 10 Hz IMU and a 1 Hz LED pose.

Loop, per 0.1 s control interval [t_k, t_k+1):
  1. the controller picks a valve configuration from the navigation estimate
     at t_k and the latest gyro samples;
  2. the truth plant integrates the interval with that configuration held;
  3. the IMU sample stamped t_k+1 (mean over the interval) drives
     NavUkf.predict(t_k+1, ...);
  4. at whole seconds the LED pose is captured; it is delivered after the
     profile's latency and fused with NavUkf.update_pose(t_capture, ...).
The run ends at contact (the inspector's docking face reaches the port
plane) or at ``t_max_s``.

Initial conditions (seeded): start direction within ``start_cone_deg`` of
the approach axis at ``start_range_m`` from the host, velocity
N(0, v0_sigma_mps = 3 mm/s) per axis (released from a hold), attitude
Exp(N(0, 0.05 rad)) from the docking attitude, body rate relative to Hill
N(0, 0.005 rad/s).

Filter initialisation (``init``):
  * "pose" (default): position and attitude from the LED pose captured at
    t = 0, with that pose's own covariance R; velocity 0 with
    P0_v = v0_sigma_mps^2 I, the true spread of the start velocity. So
    P0 = blockdiag(R_pos(t=0), (3 mm/s)^2 I, (0.01 rad)^2 I) and the initial
    error is exactly a draw from P0. The first fused pose is the one
    captured at t = 1 s.
  * "truth_draw": the truth plus a draw from
    P0 = diag(0.05 m, 0.01 m/s, 0.05 rad)^2 (per axis), and the pose captured
    at t = 0 fused at once.

Pose source (``pose_source``):
  * "synthetic" (default): bench/sim/sensors.py PoseSensor, the truth plus 5 % of
    range per axis and 0.01 rad, with the covariance of ``pose_R_from``.
  * "images": bench/sim/image_pose.py ImagePoseSensor. Each 1 Hz frame is
    rendered from the true state and run through the flight vision pipeline
    (fsw_bindings.LedPoseEstimator); the filter gets that pose with the
    covariance the pipeline reports (``pose_R_from`` does not apply). A frame
    whose status is not Ok delivers nothing and is counted by status
    (``summary.vision_status_counts``). If the frame at t = 0 gives no
    pose, the inspector holds its valves closed and the filter is started
    from the first frame that does (``summary.t_nav_init_s``).

Physical effects (``effects``: an EffectSet, bench/sim/effects.py and
docs/EFFECTS.md) change the truth plant, the truth vehicle and the sensors;
the controller and the filter keep their nominal models. Camera latency
(the frame tagged t shows the truth at t - latency, interpolated between
control steps) and the IMU clock (time tags scaled by 1 + eps; the flight
software keeps time by it, so pose frames carry the tag of their IMU tick)
act in this loop.
Without effects the run is the same, bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from bench.sim.controller import APPROACH_AXIS_HILL, DOCK_HILL_M, ControlDecision, ControllerParams, DockingController
from bench.sim.plant import N_RADPS, Plant, PlantState
from bench.sim.sensors import Imu, NoiseProfile, PoseSensor
from bench.sim.vehicle import ALL_VALVES, Vehicle
from bench.so3 import boxminus, boxplus, qexp, qnormalize, rotmat

P0_SIGMAS = np.array([0.05] * 3 + [0.01] * 3 + [0.05] * 3)  # [m, m/s, rad]
NAV_DOF = 9
POSE_DOF = 6


@dataclass
class ScenarioConfig:
    profile: NoiseProfile = field(default_factory=NoiseProfile.paper)
    dynamics: str = "nonlinear"
    dt_s: float = 0.1
    pose_period_s: float = 1.0
    start_range_m: float = 0.75
    start_cone_deg: float = 30.0
    t_max_s: float = 240.0
    # Truth RK4 substep. Against a 1 ms reference over 60 s of tumbling at
    # 0.1 rad/s with thrust: 3e-10 m, 5e-9 rad at 0.05 s (2e-8 rad at 0.1 s),
    # seven orders below the pose noise; 0.05 s halves the bench's cost per step.
    substep_s: float = 0.05
    gate_chi2: float = 22.46
    nav: str = "ukf"  # "ukf": fsw_bindings.NavUkf; "truth": the estimate is the truth (controller tests)
    # The filter's noise settings; None means "same as the simulated sensors".
    nav_accel_sigma_mps2: float | None = None
    nav_gyro_sigma_rps: float | None = None
    # "pose": r, q from the pose captured at t = 0 (its own R), v = 0 with
    # sigma v0_sigma_mps; first fused update at t = 1 s. "truth_draw": truth
    # plus a draw from P0_SIGMAS, and the t = 0 pose fused at once.
    init: str = "pose"
    # Range from which the pose covariance handed to the filter is built:
    # "estimate" (the filter's range at fusion: independent of the pose's own
    # noise) or "measurement" (the measured range: a noisy measurement then
    # carries a correlated R, which biases NIS and NEES slightly upward).
    pose_R_from: str = "estimate"
    v0_sigma_mps: float = 0.003
    controller: ControllerParams = field(default_factory=ControllerParams)
    truth_vehicle: Vehicle = field(default_factory=Vehicle)
    effects: dict | None = None  # EffectSet (bench/sim/effects.py): physics the nominal model leaves out
    # What the filter's predict takes as the specific force during firings:
    # "imu" (the accelerometer) or "blr" (the flight BLR's prediction for the
    # valve configuration, Rogers-Marcovitz section 3's conclusion). The learner
    # (fsw_bindings.ThrusterBlr, window 30) learns online from the firing
    # steps themselves: accelerometer x dt as the body dv, the gyro's change
    # as dw; it stands in once it holds blr_min_samples samples and where the
    # sigma of its mean is below the filter's accelerometer sigma, and each
    # prediction is made before that step's sample is entered.
    accel_source: str = "imu"
    blr_min_samples: int = 30
    # Open loop: fire this valve-configuration sequence (one per step) instead
    # of the controller's choices, for exactly its length (no contact stop).
    # Replaying a closed-loop run's valves with an effect switched on gives
    # that effect's signature without the controller's feedback.
    valve_script: tuple | None = None
    # "synthetic": PoseSensor (bench/sim/sensors.py); "images": rendered images of
    # the host's LED pattern through the flight vision pipeline (bench/sim/image_pose.py).
    pose_source: str = "synthetic"


@dataclass
class PoseUpdates:
    """One row per pose delivered to the filter, in delivery order."""

    t_capture: np.ndarray  # capture time tag [s]
    t_fused: np.ndarray  # when it was fused, on the IMU's clock [s]
    nis: np.ndarray
    status: np.ndarray  # the filter's update status (str)
    fused: np.ndarray  # bool
    innovation: np.ndarray  # (N, 6)
    S: np.ndarray  # (N, 6, 6) innovation covariance
    loglik: np.ndarray
    r_meas: np.ndarray  # (N, 3) [m]
    q_meas: np.ndarray  # (N, 4)
    r_sigma: np.ndarray  # 1-sigma of the position handed to the filter [m]
    att_sigma: np.ndarray  # 1-sigma of the attitude [rad]


@dataclass
class DockingSummary:
    seed: int
    docked: bool  # reached contact before t_max_s
    t_end_s: float
    contact_speed_mps: float  # along the approach axis at the end
    lateral_miss_m: float
    attitude_miss_rad: float
    first_update_t_s: float | None  # first pose delivered to the filter (None: none)
    valve_seconds: float
    firing_steps: int
    blr_steps: int  # firing steps whose predict took the BLR's specific force
    pose_source: str = "synthetic"
    vision_status_counts: dict = field(default_factory=dict)  # images: the vision pipeline's status per frame
    t_nav_init_s: float | None = 0.0  # images: when a frame first gave a pose (None: never)
    cut_by_duration: bool = False  # HIL: not docked because the HIL run's time ran out


@dataclass
class DockingRun:
    """Time histories of one docking run: one row at the start and one per
    control step (``config``: one per step)."""

    t: np.ndarray  # (N,) [s]
    r_true: np.ndarray  # (N, 3) Hill [m]
    v_true: np.ndarray  # (N, 3) Hill [m/s]
    q_true: np.ndarray  # (N, 4) q_hb
    w_true: np.ndarray  # (N, 3) omega_bi_b [rad/s]
    est: np.ndarray  # (N, 10) the filter's [r, v, q] (NaN before it starts)
    P: np.ndarray  # (N, 9, 9)
    nees: np.ndarray  # (N,)
    config: np.ndarray  # (N - 1,) valve configuration of each step (int)
    predict_status: np.ndarray  # (N,) str
    updates: PoseUpdates
    imu_t: np.ndarray  # (M,) IMU time tags [s]
    imu_accel: np.ndarray  # (M, 3) [m/s^2]
    imu_gyro: np.ndarray  # (M, 3) [rad/s]
    summary: DockingSummary

    @classmethod
    def from_record(cls, d: dict) -> DockingRun:
        """A run as a results store gives it back (dataclasses as dicts,
        bench/runner/records.py)."""
        return cls(**{**d, "updates": PoseUpdates(**d["updates"]), "summary": DockingSummary(**d["summary"])})


class _TruthNav:
    """Perfect navigation, for exercising the controller and plant alone."""

    def __init__(self, plant: Plant):
        self.plant = plant
        self.P = None

    def state(self):
        s = self.plant.state
        return np.concatenate([s.r_hill_m, s.v_hill_mps, s.q_hb])


def nav_config(cfg: ScenarioConfig):
    """fsw_bindings.NavConfig whose noise settings are the simulated sensors'."""
    import fsw_bindings as fb

    nc = fb.NavConfig()
    nc.n_radps = fb.orbit_rate(fb.EARTH_RADIUS + 500e3)
    nc.dt_imu_s = cfg.dt_s
    nc.accel_sigma_mps2 = cfg.profile.accel_sigma_mps2 if cfg.nav_accel_sigma_mps2 is None else cfg.nav_accel_sigma_mps2
    nc.gyro_sigma_rps = cfg.profile.gyro_sigma_rps if cfg.nav_gyro_sigma_rps is None else cfg.nav_gyro_sigma_rps
    nc.gate_chi2 = cfg.gate_chi2
    nc.max_delay_s = 0.5
    return nc


def make_nav_ukf(cfg: ScenarioConfig):
    import fsw_bindings as fb

    return fb.NavUkf(nav_config(cfg))


def initial_truth(rng: np.random.Generator, cfg: ScenarioConfig) -> PlantState:
    # Direction within the start cone around -approach axis.
    ang = np.deg2rad(cfg.start_cone_deg) * np.sqrt(rng.uniform())
    az = rng.uniform(0.0, 2 * np.pi)
    u = np.array([np.sin(ang) * np.cos(az), -np.cos(ang), np.sin(ang) * np.sin(az)])
    r0 = cfg.start_range_m * u
    v0 = cfg.v0_sigma_mps * rng.standard_normal(3)
    q0 = qnormalize(qexp(0.05 * rng.standard_normal(3)))
    w_bh = 0.005 * rng.standard_normal(3)
    w_bi = w_bh + rotmat(q0).T @ np.array([0.0, 0.0, N_RADPS])
    return PlantState(0.0, r0, v0, q0, w_bi)


def nav_error(truth_r, truth_v, truth_q, est):
    """[r_true - r_est, v_true - v_est, boxminus(q_true, q_est)] (9,)."""
    return np.concatenate([truth_r - est[0:3], truth_v - est[3:6], boxminus(truth_q, est[6:10])])


def run_docking(seed: int, cfg: ScenarioConfig | None = None, nav=None, on_step=None) -> DockingRun:
    """One docking run: its time histories, pose updates, IMU samples and
    summary. ``nav``: any object with NavUkf's interface (the HIL link's
    LinkNav); None builds the in-process filter. ``on_step(t)`` is called
    after each IMU sample."""
    return _DockingLoop(seed, cfg or ScenarioConfig(), nav, on_step).run()


@dataclass
class _Truth:
    """The truth plant and the sensors as the effects make them."""

    plant: Plant
    imu: Imu
    pose: object  # PoseSensor or ImagePoseSensor
    latency_s: float = 0.0  # camera latency: the frame tagged t shows the truth at t - latency
    clock_rate: float = 1.0  # the IMU clock runs at this rate (1 + eps)


def _truth_and_sensors(cfg: ScenarioConfig, seed: int, images: bool, rng_imu, rng_pose, rng_init) -> _Truth:
    lens_k1 = 0.0
    if cfg.effects:
        from bench.sim.effects import realise

        fx = realise(cfg.effects, cfg.truth_vehicle, cfg.profile, seed)
        plant = Plant(
            initial_truth(rng_init, cfg),
            vehicle=fx.vehicle,
            dynamics=cfg.dynamics,
            substep_s=cfg.substep_s,
            effects=fx.plant,
        )
        imu = Imu(fx.profile, rng_imu, c_imu_b=fx.c_imu_b)
        if images and (fx.lever_arm_b_m is not None or fx.occlusion is not None):
            raise ValueError("pose_source 'images' does not model the camera lever arm or LED occlusion effects")
        if fx.lens_k1 != 0.0 and not images:
            raise ValueError("lens_distortion needs pose_source 'images' (the synthetic pose sensor has no lens)")
        lens_k1 = fx.lens_k1
        point = fx.lever_arm_b_m
        if fx.pose_point_b_m is not None:
            point = fx.pose_point_b_m + (point if point is not None else 0.0)
        pose = PoseSensor(cfg.profile, rng_pose, lever_arm_b_m=point, occlusion=fx.occlusion)
        truth = _Truth(plant, imu, pose, fx.camera_latency_s, fx.imu_clock_rate)
    else:
        plant = Plant(
            initial_truth(rng_init, cfg), vehicle=cfg.truth_vehicle, dynamics=cfg.dynamics, substep_s=cfg.substep_s
        )
        truth = _Truth(plant, Imu(cfg.profile, rng_imu), PoseSensor(cfg.profile, rng_pose))
    if images:
        from bench.sim.image_pose import ImagePoseSensor

        truth.pose = ImagePoseSensor(cfg.profile, rng_pose, lens_k1=lens_k1)
    return truth


class _History:
    """The time histories, one row per record (the start and each step)."""

    KEYS = ("t", "r_true", "v_true", "q_true", "w_true", "est", "P", "nees", "config", "predict_status")

    def __init__(self):
        self.rows = {k: [] for k in self.KEYS}

    def record(self, s: PlantState, nav, nav_ready: bool, status: str) -> None:
        h = self.rows
        est = np.asarray(nav.state(), float) if nav_ready else np.full(10, np.nan)
        h["t"].append(s.t_s)
        h["r_true"].append(s.r_hill_m.copy())
        h["v_true"].append(s.v_hill_mps.copy())
        h["q_true"].append(s.q_hb.copy())
        h["w_true"].append(s.omega_bi_b_rps.copy())
        h["est"].append(est)
        P = None if (nav.P is None or not nav_ready) else np.asarray(nav.P, float)
        h["P"].append(np.full((9, 9), np.nan) if P is None else P)
        if P is None:
            h["nees"].append(np.nan)
        else:
            e = nav_error(s.r_hill_m, s.v_hill_mps, s.q_hb, est)
            h["nees"].append(float(e @ np.linalg.solve(P, e)))
        h["predict_status"].append(status)

    def seen(self, s: PlantState, t_tag: float, latency_s: float):
        """(r, q) the camera sees in the frame tagged t_tag: the truth at
        t_tag - latency, interpolated over the recorded control steps (``s``
        is the truth now)."""
        tc = max(t_tag - latency_s, 0.0)
        if latency_s == 0.0 or tc >= s.t_s:
            return s.r_hill_m, s.q_hb
        h = self.rows
        ts = h["t"] + [s.t_s]
        rs, qs = h["r_true"] + [s.r_hill_m], h["q_true"] + [s.q_hb]
        j = min(max(int(np.searchsorted(ts, tc, side="right")) - 1, 0), len(ts) - 1)
        if j == len(ts) - 1:
            return rs[j], qs[j]
        f = (tc - ts[j]) / (ts[j + 1] - ts[j])
        return rs[j] + f * (rs[j + 1] - rs[j]), boxplus(qs[j], f * boxminus(qs[j + 1], qs[j]))


class _UpdateLog:
    """The pose updates delivered to the filter (PoseUpdates, as lists)."""

    def __init__(self):
        self.rows = {f.name: [] for f in fields(PoseUpdates)}

    def append(self, m, rec, R: np.ndarray, t_fused: float) -> None:
        u = self.rows
        u["t_capture"].append(m.t_capture_s)
        u["t_fused"].append(t_fused)
        u["nis"].append(rec.nis)
        u["status"].append(rec.status)
        u["fused"].append(bool(rec.fused))
        u["innovation"].append(np.asarray(rec.innovation))
        u["S"].append(np.asarray(rec.innovation_cov))
        u["loglik"].append(rec.log_likelihood)
        u["r_meas"].append(np.asarray(m.r_hill_m, float))
        u["q_meas"].append(np.asarray(m.q_hb, float))
        u["r_sigma"].append(float(np.sqrt(R[0, 0])))
        u["att_sigma"].append(float(np.sqrt(R[3, 3])))

    def arrays(self) -> PoseUpdates:
        a = {key: np.array(v) for key, v in self.rows.items()}
        a["r_meas"] = a["r_meas"].reshape(-1, 3)
        a["innovation"] = a["innovation"].reshape(-1, 6)
        a["q_meas"] = a["q_meas"].reshape(-1, 4)
        return PoseUpdates(**a)


class _SpecificForce:
    """What the filter's predict takes as the specific force
    (``ScenarioConfig.accel_source``): the accelerometer, or during firings
    the flight BLR's prediction once it knows the configuration well enough."""

    def __init__(self, cfg: ScenarioConfig, gyro0):
        if cfg.accel_source not in ("imu", "blr"):
            raise ValueError(f"accel_source must be 'imu' or 'blr', not {cfg.accel_source!r}")
        self.learner = None
        if cfg.accel_source == "blr":
            import fsw_bindings as fb

            self.learner = fb.ThrusterBlr(prior_precision=1e-3)
        self.dt_s, self.min_samples = cfg.dt_s, cfg.blr_min_samples
        self.accel_sigma_nav = (
            cfg.profile.accel_sigma_mps2 if cfg.nav_accel_sigma_mps2 is None else cfg.nav_accel_sigma_mps2
        )
        self.count, self.used, self.gyro_prev = 0, 0, gyro0

    def for_predict(self, config: int, sample):
        """The specific force for this step's predict; the learner then
        learns from the step (each prediction is made before its sample)."""
        accel_nav = sample.accel_b_mps2
        if self.learner is not None and config != 0:
            if self.count >= self.min_samples:
                mean, var_mean = self.learner.mean_and_its_variance_mask(int(config))
                # Only where the learner knows this configuration's effect
                # better than the accelerometer measures it (the filter's
                # noise model); a rarely seen configuration stays on the IMU.
                if np.sqrt(np.max(var_mean[0:3])) / self.dt_s < self.accel_sigma_nav:
                    accel_nav = mean[0:3] / self.dt_s
                    self.used += 1
            dw = np.asarray(sample.omega_bi_b_rps, float) - np.asarray(self.gyro_prev, float)
            self.learner.add_mask(int(config), np.concatenate([np.asarray(sample.accel_b_mps2, float) * self.dt_s, dw]))
            self.count += 1
        self.gyro_prev = sample.omega_bi_b_rps
        return accel_nav


def _init_from_pose(nav, cfg: ScenarioConfig, t_s: float, m0) -> None:
    """Filter start from a pose: its r, q and R; v = 0 with sigma v0_sigma_mps."""
    P0 = np.zeros((9, 9))
    P0[0:3, 0:3], P0[6:9, 6:9] = m0.R[0:3, 0:3], m0.R[3:6, 3:6]
    P0[3:6, 3:6] = cfg.v0_sigma_mps**2 * np.eye(3)
    nav.init(t_s, m0.r_hill_m, np.zeros(3), m0.q_hb, P0)


class _DockingLoop:
    """One run of the loop of the module docstring; ``run()`` returns it."""

    def __init__(self, seed: int, cfg: ScenarioConfig, nav, on_step):
        self.seed, self.cfg, self.on_step = seed, cfg, on_step
        rng = np.random.default_rng(seed)
        rng_imu, rng_pose, rng_init, rng_p0 = (np.random.default_rng(s) for s in rng.integers(0, 2**63, 4))
        if cfg.pose_source not in ("synthetic", "images"):
            raise ValueError(f"pose_source must be 'synthetic' or 'images', not {cfg.pose_source!r}")
        self.images = cfg.pose_source == "images"
        truth = _truth_and_sensors(cfg, seed, self.images, rng_imu, rng_pose, rng_init)
        self.plant, self.imu, self.pose = truth.plant, truth.imu, truth.pose
        self.latency_s, self.clock_rate = truth.latency_s, truth.clock_rate
        self.ctrl = DockingController(params=cfg.controller)
        self.hist, self.updates = _History(), _UpdateLog()
        self.imu_log = {"t": [], "accel": [], "gyro": []}
        self.pending = []  # poses captured, not yet delivered
        self.first_update_t = None
        self.nav_ready = True  # False only while image poses have not yet given a first fix
        self.t_nav_init = 0.0
        self.nav = self._start_nav(nav, rng_p0)

    def seen(self, t_tag: float):
        return self.hist.seen(self.plant.state, t_tag, self.latency_s)

    def _start_nav(self, nav, rng_p0):
        cfg = self.cfg
        if cfg.nav == "truth":
            return _TruthNav(self.plant)
        if cfg.nav != "ukf":
            raise ValueError(f"nav must be 'ukf' or 'truth', not {cfg.nav!r}")
        nav = make_nav_ukf(cfg) if nav is None else nav
        if cfg.init == "pose":
            m0 = self.pose.measure(0.0, *self.seen(0.0))
            if m0 is None:  # images: no pose in the first frame
                self.nav_ready, self.t_nav_init = False, None
            else:
                _init_from_pose(nav, cfg, 0.0, m0)
        elif cfg.init == "truth_draw":
            s0 = self.plant.state
            d0 = P0_SIGMAS * rng_p0.standard_normal(NAV_DOF)
            P0 = np.diag(P0_SIGMAS**2)
            nav.init(0.0, s0.r_hill_m + d0[0:3], s0.v_hill_mps + d0[3:6], boxplus(s0.q_hb, -d0[6:9]), P0)
        else:
            raise ValueError(f"init must be 'pose' or 'truth_draw', not {cfg.init!r}")
        return nav

    def run(self) -> DockingRun:
        cfg = self.cfg
        gyro_last = self.plant.state.omega_bi_b_rps.copy()  # before the first sample: the initial rate
        if not (cfg.nav == "ukf" and cfg.init == "pose"):
            m0 = self.pose.measure(0.0, *self.seen(0.0))
            if m0 is not None:
                self.pending.append(m0)
            self._deliver(0.0)
        self._record("init")
        force = _SpecificForce(cfg, gyro_last)
        k, contact = 0, False
        while self.plant.state.t_s < cfg.t_max_s - 1e-9:
            dec = self._decide(k, gyro_last)
            if dec is None:
                break
            gyro_last, contact = self._step(k, dec, force)
            k += 1
            if contact:
                break
        return self._result(contact, force.used)

    def _decide(self, k: int, gyro_last) -> ControlDecision | None:
        """The step's valves: closed while waiting for a first pose, the
        script's (None when it has run out), or the controller's."""
        est = np.asarray(self.nav.state(), float) if self.nav_ready else None
        script = self.cfg.valve_script
        if not self.nav_ready:
            return ControlDecision(0, ALL_VALVES[0].copy(), np.zeros(3), np.zeros(3), "wait")
        if script is not None:
            if k >= len(script):
                return None
            c = int(script[k])
            return ControlDecision(c, ALL_VALVES[c].copy(), np.zeros(3), np.zeros(3), "script")
        return self.ctrl.step(est[0:3], est[3:6], est[6:10], gyro_last)

    def _step(self, k: int, dec: ControlDecision, force: _SpecificForce):
        """Control interval k: plant, IMU, predict, pose capture and delivery.
        Returns the gyro sample and whether the inspector made contact."""
        cfg = self.cfg
        if hasattr(self.nav, "note_valves"):  # the flight app's thruster learner hears the command
            self.nav.note_valves(k * cfg.dt_s, cfg.dt_s, int(dec.config))
        step = self.plant.step(dec.valves, cfg.dt_s)
        t = (k + 1) * cfg.dt_s
        t_imu = t if self.clock_rate == 1.0 else t * self.clock_rate  # the IMU's own (drifting) time tag
        sample = self.imu.sample(t_imu, step.specific_force_b_mps2, step.omega_mean_bi_b_rps)
        self.imu_log["t"].append(t_imu)
        self.imu_log["accel"].append(np.asarray(sample.accel_b_mps2, float))
        self.imu_log["gyro"].append(np.asarray(sample.omega_bi_b_rps, float))
        if self.on_step is not None:
            self.on_step(t)
        accel_nav = force.for_predict(dec.config, sample)
        status = "ok"
        if cfg.nav == "ukf" and self.nav_ready:
            status = self.nav.predict(t_imu, accel_nav, sample.omega_bi_b_rps).status
        elif not self.nav_ready:
            status = "waiting_for_pose"
        if (k + 1) % int(round(cfg.pose_period_s / cfg.dt_s)) == 0:
            self._capture(t, t_imu)
        self._deliver(t)
        self._record(status)
        self.hist.rows["config"].append(dec.config)
        d_axial = float((DOCK_HILL_M - self.plant.state.r_hill_m) @ APPROACH_AXIS_HILL)
        return sample.omega_bi_b_rps, d_axial <= 0.0 and cfg.valve_script is None

    def _capture(self, t: float, t_imu: float) -> None:
        """The pose of the frame at t: it starts the filter if it waits for
        one, else it is delivered after the latency."""
        m = self.pose.measure(t, *self.seen(t))
        if m is not None and self.clock_rate != 1.0:
            m.t_capture_s = t_imu  # the flight clock (the IMU's) tags the frame with its tick
        if m is not None and not self.nav_ready:
            _init_from_pose(self.nav, self.cfg, m.t_capture_s, m)
            self.nav_ready, self.t_nav_init = True, m.t_capture_s
        elif m is not None:
            self.pending.append(m)

    def _deliver(self, t_now: float) -> None:
        """Fuse every pending pose due by t_now."""
        cfg = self.cfg
        while self.pending and self.pending[0].t_deliver_s <= t_now + 1e-9:
            m = self.pending.pop(0)
            if cfg.nav != "ukf":
                continue
            if self.images or cfg.pose_R_from == "measurement":
                R = m.R
            else:
                R = self.pose.covariance(np.asarray(self.nav.r_hill_m, float))
            rec = self.nav.update_pose(m.t_capture_s, m.r_hill_m, m.q_hb, R)
            self.updates.append(m, rec, R, t_now if self.clock_rate == 1.0 else t_now * self.clock_rate)
            if self.first_update_t is None:
                self.first_update_t = t_now

    def _record(self, status: str) -> None:
        self.hist.record(self.plant.state, self.nav, self.nav_ready, status)

    def _result(self, contact: bool, blr_used: int) -> DockingRun:
        h = self.hist.rows
        out = {key: np.array(v) for key, v in h.items()}
        out["config"] = np.array(h["config"], dtype=int)
        return DockingRun(
            **out,
            updates=self.updates.arrays(),
            imu_t=np.array(self.imu_log["t"]),
            imu_accel=np.array(self.imu_log["accel"]).reshape(-1, 3),
            imu_gyro=np.array(self.imu_log["gyro"]).reshape(-1, 3),
            summary=self._summary(contact, blr_used),
        )

    def _summary(self, contact: bool, blr_used: int) -> DockingSummary:
        s, config = self.plant.state, self.hist.rows["config"]
        e_lat = s.r_hill_m - DOCK_HILL_M
        e_lat = e_lat - (e_lat @ APPROACH_AXIS_HILL) * APPROACH_AXIS_HILL
        out = DockingSummary(
            seed=int(self.seed),
            docked=bool(contact),
            t_end_s=float(s.t_s),
            contact_speed_mps=float(s.v_hill_mps @ APPROACH_AXIS_HILL),
            lateral_miss_m=float(np.linalg.norm(e_lat)),
            attitude_miss_rad=float(np.linalg.norm(boxminus(s.q_hb, self.ctrl.q_des_hb))),
            first_update_t_s=self.first_update_t,
            valve_seconds=float(np.sum([bin(c).count("1") for c in config]) * self.cfg.dt_s),
            firing_steps=int(np.count_nonzero(config)),
            blr_steps=int(blr_used),
            t_nav_init_s=self.t_nav_init,
        )
        if self.images:
            out.pose_source = "images"
            out.vision_status_counts = dict(self.pose.status_counts)
        return out


@dataclass(frozen=True)
class NavErrors:
    """The filter's errors against the truth from the first pose update on."""

    t: np.ndarray  # (N,) time [s]
    pos: np.ndarray  # (N, 3) position error, Hill frame [m]
    vel: np.ndarray  # (N, 3) velocity error, Hill frame [m/s]
    att: np.ndarray  # (N, 3) attitude error, body frame [rad]
    sigma: np.ndarray  # (N, 9) the matching 1-sigma bounds from P
    nees: np.ndarray  # (N,) normalised estimation error squared

    def block(self, name: str) -> np.ndarray:
        """``pos``, ``vel`` or ``att`` by name."""
        return {"pos": self.pos, "vel": self.vel, "att": self.att}[name]


def errors_from_first_update(run: DockingRun) -> NavErrors:
    """Per-axis errors (N, 3) of position, velocity and attitude from the first
    pose update on, with the matching 1-sigma bounds from P."""
    t0 = run.summary.first_update_t_s
    sel = run.t >= (t0 if t0 is not None else np.inf) - 1e-9
    est = run.est[sel]
    e = np.array([nav_error(r, v, q, x) for r, v, q, x in zip(run.r_true[sel], run.v_true[sel], run.q_true[sel], est)])
    sig = np.sqrt(np.array([np.diag(P) for P in run.P[sel]]))
    return NavErrors(t=run.t[sel], pos=e[:, 0:3], vel=e[:, 3:6], att=e[:, 6:9], sigma=sig, nees=run.nees[sel])
