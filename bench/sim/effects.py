"""The effect library: physics the nominal model leaves out, each a switch
with a magnitude, injected into the truth plant and the sensors.

An effect is named in ``EFFECTS`` (its ``EffectSpec``: kind, unit, number of
parameters, a typical magnitude, the smallest magnitude that shows as a gap
in a 120 s docking run, and a seeded draw). An ``EffectSet`` (name -> params)
given to ``ScenarioConfig(effects=...)`` switches effects on; ``realise``
turns it into the physical settings of the plant (bench/sim/plant.py,
``PlantEffects``), the truth vehicle (bench/sim/vehicle.py), the sensors
(bench/sim/sensors.py) and the scenario loop (camera latency, IMU clock). The
equations live there, not here: this module only maps parameters to physics.

``in_library`` marks the effects a diagnoser may use as candidates; the
others (fuel slosh, IMU clock drift, LED occlusion, a flexible mode, lens
distortion) exist to test that a gap
no candidate explains is reported as unexplained. Every effect, its physics,
its parameters and how ``min_detectable`` was measured: docs/EFFECTS.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from bench.sim.plant import PlantEffects
from bench.sim.sensors import NoiseProfile
from bench.sim.vehicle import DIRECTIONS_B, N_THRUSTERS, Vehicle
from bench.so3 import qexp, rotmat


def _unit(rng: np.random.Generator, n: int = 3) -> np.ndarray:
    u = rng.standard_normal(n)
    return u / np.linalg.norm(u)


def _norm(p: np.ndarray) -> float:
    return float(np.linalg.norm(p))


def _first(p: np.ndarray) -> float:
    return float(abs(p[0]))


def _rms_rows(p: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(np.asarray(p).reshape(N_THRUSTERS, -1) ** 2, axis=1))))


def _draw_misalignment(rng, size):
    # Each nozzle tilted by `size` rad in a random direction perpendicular to its thrust.
    out = np.zeros((N_THRUSTERS, 3))
    for i, d in enumerate(DIRECTIONS_B):
        u = _unit(rng)
        u = u - (u @ d) * d
        out[i] = size * u / np.linalg.norm(u)
    return out.ravel()


def _draw_loss(rng, size):
    # Non-negative losses of random spread with RMS `size`.
    u = rng.uniform(0.2, 1.0, N_THRUSTERS)
    return size * u / np.sqrt(np.mean(u**2))


@dataclass(frozen=True)
class EffectSpec:
    name: str
    kind: str  # "dynamics" or "sensor"
    in_library: bool
    n_params: int
    unit: str
    description: str
    typical: float
    min_detectable: float
    param_names: tuple = ()
    size_fn: Callable = field(default=_norm, repr=False)
    draw_fn: Callable = field(default=None, repr=False)  # (rng, size) -> params
    max_size: float = np.inf  # largest physically sensible size (bounds the min_detectable search)
    # True when no sensor-only statistic shows the effect in a docking run up
    # to max_size: min_detectable then comes from the navigation error against
    # truth (docs/EFFECTS.md), so only a log with truth shows it.
    needs_truth: bool = False
    # False when not even the truth shows the effect in a 120 s docking run up
    # to max_size, nor the diagnoser's screen in a docking-then-characterisation
    # log: min_detectable is then max_size, a bound, not a measurement.
    detectable: bool = True
    # True when the effect lives in the camera and so exists only with pose
    # from rendered images (ScenarioConfig(pose_source="images")); the bench's
    # synthetic pose sensor has no lens.
    needs_images: bool = False

    def size(self, params) -> float:
        """The effect's magnitude (the quantity ``typical`` and ``min_detectable`` measure)."""
        return self.size_fn(canonical(self.name, params))

    def at(self, unit_params, size: float) -> np.ndarray:
        """``unit_params`` (a draw at size 1) taken to ``size``: the size
        parameters scale, the others (a frequency, a phase, a fraction) stay."""
        p = np.asarray(unit_params, float).ravel().copy()
        keep = _FIXED_PARAMS.get(self.name, ())
        scale = np.ones(p.size, bool)
        scale[list(keep)] = False
        p[scale] *= size
        return p

    def draw(self, rng: np.random.Generator, scale: float) -> np.ndarray:
        """A parameter vector of size ``scale * min_detectable``, random
        direction and sign where the effect has them."""
        p = np.asarray(self.draw_fn(rng, scale * self.min_detectable), float).ravel()
        assert p.size == self.n_params
        return p


def _vec3_draw(rng, size):
    return size * _unit(rng)


def _pos_draw(rng, size):
    return np.array([size])


def _signed_draw(rng, size):
    return np.array([size * rng.choice([-1.0, 1.0])])


def _draw_drag(rng, size):
    # Both ballistic coefficients non-negative: B_inspector = dB + B_host.
    db = size * rng.choice([-1.0, 1.0])
    return np.array([db, max(0.0, -db) + rng.uniform(0.0, 1.0) * abs(db)])


# Parameters that do not scale with an effect's size (EffectSpec.at).
_FIXED_PARAMS = {"host_eccentricity": (1,), "flex_mode": (0,), "led_occlusion": (1,)}

# min_detectable: measured with `python -m bench.campaigns.detect` (docs/EFFECTS.md);
# lens distortion on image-pose docking runs (`--effects lens_distortion`).
LENS_K1_MIN_DETECTABLE = 0.029
# Clock drift: no gap statistic of a docking run shows it up to 0.05; the
# diagnoser's screen with its clock candidate does on docking-then-
# characterisation logs (bench/campaigns/gap/detectable.py, docs/EFFECTS.md).
CLOCK_DRIFT_MIN_DETECTABLE = 0.0025
EFFECTS: dict[str, EffectSpec] = {
    s.name: s
    for s in (
        EffectSpec(
            "thruster_misalignment",
            "dynamics",
            True,
            24,
            "rad",
            "rotation vector of each nozzle's thrust direction (8 x 3, body axes; size: RMS angle)",
            0.02,
            1.28e-3,
            tuple(f"phi{i}_{a}" for i in range(8) for a in "xyz"),
            _rms_rows,
            _draw_misalignment,
        ),
        EffectSpec(
            "thrust_loss",
            "dynamics",
            True,
            8,
            "1",
            "fractional thrust magnitude loss per valve (8, or 1 common to all; size: RMS)",
            0.05,
            3.1e-3,
            tuple(f"loss{i}" for i in range(8)),
            _rms_rows,
            _draw_loss,
        ),
        EffectSpec(
            "com_offset",
            "dynamics",
            True,
            3,
            "m",
            "centre of mass offset from the body origin (body axes): thrust torques and the accelerometer's lever arm",
            0.005,
            8.7e-4,
            ("dx", "dy", "dz"),
            _norm,
            _vec3_draw,
        ),
        EffectSpec(
            "mass_depletion",
            "dynamics",
            True,
            1,
            "kg/s",
            "propellant flow per open valve; mass falls with the valve-seconds used",
            3.4e-5,
            9.2e-3,
            ("mdot",),
            _first,
            _pos_draw,
        ),
        EffectSpec(
            "accel_bias",
            "sensor",
            True,
            3,
            "m/s^2",
            "constant accelerometer bias (IMU axes)",
            5e-4,
            2.7e-4,
            ("bx", "by", "bz"),
            _norm,
            _vec3_draw,
        ),
        EffectSpec(
            "gyro_bias",
            "sensor",
            True,
            3,
            "rad/s",
            "constant gyro bias (IMU axes)",
            5e-4,
            8.8e-4,
            ("bx", "by", "bz"),
            _norm,
            _vec3_draw,
        ),
        EffectSpec(
            "gyro_scale",
            "sensor",
            True,
            3,
            "1",
            "gyro scale-factor error per axis",
            0.01,
            0.065,
            ("sx", "sy", "sz"),
            _norm,
            _vec3_draw,
        ),
        EffectSpec(
            "imu_misalignment",
            "sensor",
            True,
            3,
            "rad",
            "rotation vector of the IMU axes relative to the body axes",
            0.005,
            0.067,
            ("phix", "phiy", "phiz"),
            _norm,
            _vec3_draw,
        ),
        EffectSpec(
            "camera_latency",
            "sensor",
            True,
            1,
            "s",
            "the pose is captured this long before its time tag",
            0.05,
            2.09,
            ("latency",),
            _first,
            _pos_draw,
        ),
        EffectSpec(
            "camera_lever_arm",
            "sensor",
            True,
            3,
            "m",
            "the pose solution refers to a point d from the centre of mass (body): r_meas = r + C(q) d",
            0.02,
            0.021,
            ("dx", "dy", "dz"),
            _norm,
            _vec3_draw,
        ),
        EffectSpec(
            "host_eccentricity",
            "dynamics",
            True,
            2,
            "1",
            "host orbit eccentricity (and true anomaly at t = 0, rad); the filter assumes a circular host",
            1e-3,
            0.05,
            ("e", "f0"),
            _first,
            lambda rng, size: np.array([size, rng.uniform(0.0, 2 * np.pi)]),
        ),
        EffectSpec(
            "differential_j2",
            "dynamics",
            True,
            1,
            "1",
            "J2 coefficient acting on host and inspector (differential acceleration)",
            1.08262668e-3,
            100.0,
            ("j2",),
            _first,
            _pos_draw,
        ),
        EffectSpec(
            "differential_drag",
            "dynamics",
            True,
            2,
            "m^2/kg",
            "ballistic coefficient C_d A / m of the inspector minus the host's, and the host's own "
            "(rho = 5e-13 kg/m^3); the inspector's accelerometer senses its own drag (size: the difference)",
            0.015,
            18.7,
            ("dB", "B_host"),
            _first,
            _draw_drag,
        ),
        # No diagnoser candidate models a flexible mode: out of its library.
        EffectSpec(
            "flex_mode",
            "dynamics",
            False,
            2,
            "Hz, rad",
            "flexible appendage mode about body z: coupled frequency and body-angle amplitude (size: amplitude)",
            0.005,
            4.1e-3,
            ("freq_hz", "amplitude_rad"),
            lambda p: float(abs(p[1])),
            lambda rng, size: np.array([np.exp(rng.uniform(np.log(0.1), np.log(1.0))), size]),
        ),
        EffectSpec(
            "fuel_slosh",
            "dynamics",
            False,
            1,
            "kg",
            "slosh mass on a 0.3 Hz damped spring in the tank, coupled to translation",
            0.1,
            0.30,
            ("mass",),
            _first,
            _pos_draw,
        ),
        EffectSpec(
            "clock_drift",
            "sensor",
            True,
            1,
            "1",
            "the IMU clock runs fast: its time tags are (1 + eps) t",
            1e-4,
            CLOCK_DRIFT_MIN_DETECTABLE,
            ("eps",),
            _first,
            _pos_draw,
        ),
        EffectSpec(
            "led_occlusion",
            "sensor",
            False,
            2,
            "m, 1",
            "on a random fraction of frames the position is biased along the line of sight (bias, fraction)",
            0.02,
            0.057,
            ("bias_m", "fraction"),
            _first,
            lambda rng, size: np.array([size * rng.choice([-1.0, 1.0]), rng.uniform(0.2, 0.5)]),
        ),
        # Pose from images only; no diagnoser candidate models a lens.
        EffectSpec(
            "lens_distortion",
            "sensor",
            False,
            1,
            "1",
            "radial lens distortion k1 of the docking camera, left out of the vision pipeline's pinhole model",
            0.05,
            LENS_K1_MIN_DETECTABLE,
            ("k1",),
            _first,
            _signed_draw,
        ),
    )
}

# Largest physically sensible sizes (the min_detectable search stops there).
_MAX_SIZE = {
    "thruster_misalignment": 0.5,
    "thrust_loss": 0.9,
    "com_offset": 0.08,
    "mass_depletion": 0.02,
    "accel_bias": 0.05,
    "gyro_bias": 0.05,
    "gyro_scale": 0.5,
    "imu_misalignment": 0.5,
    "camera_latency": 3.0,
    "camera_lever_arm": 2.0,
    "host_eccentricity": 0.05,
    "differential_j2": 100.0,
    "differential_drag": 1000.0,
    "flex_mode": 0.5,
    "fuel_slosh": 1.5,
    "clock_drift": 0.05,
    "led_occlusion": 1.0,
    "lens_distortion": 0.3,
}
# Measured (docs/EFFECTS.md): shown only by the error against truth; not shown
# at all up to max_size (min_detectable is then max_size, a bound).
_NEEDS_TRUTH = {"camera_lever_arm"}
_NOT_DETECTABLE = {"host_eccentricity", "differential_j2"}
_NEEDS_IMAGES = {"lens_distortion"}
EFFECTS = {
    n: replace(
        s,
        max_size=_MAX_SIZE[n],
        needs_truth=n in _NEEDS_TRUTH,
        detectable=n not in _NOT_DETECTABLE,
        needs_images=n in _NEEDS_IMAGES,
    )
    for n, s in EFFECTS.items()
}


def max_size_for(name: str, vehicle=None) -> float:
    """The largest sensible size of effect ``name`` on the described vehicle
    (a bench.sim.log_description.Resolved): a camera lever arm cannot reach past
    the vehicle (``envelope_m``), and no valve expels propellant faster than
    its thrust allows at the lowest specific impulse of any thruster
    (``max_mass_flow_kgps``). Without a vehicle, the library's size."""
    top = EFFECTS[name].max_size
    if vehicle is not None and name == "camera_lever_arm":
        return float(min(top, vehicle.envelope_m))
    if vehicle is not None and name == "mass_depletion":
        return float(min(top, vehicle.max_mass_flow_kgps))
    return float(top)


# Effects that wait for a part of the bench not yet built (none now: lens
# distortion joined with the image pipeline).
PENDING: dict[str, str] = {}


def canonical(name: str, params) -> np.ndarray:
    """Params of effect ``name`` as a float vector of its n_params
    (thrust_loss also takes one common loss)."""
    if name not in EFFECTS:
        raise KeyError(f"unknown effect {name!r} (known: {', '.join(EFFECTS)})")
    spec = EFFECTS[name]
    p = np.atleast_1d(np.asarray(params, dtype=float)).ravel()
    if name == "thrust_loss" and p.size == 1:
        p = np.full(N_THRUSTERS, p[0])
    if name == "differential_drag" and p.size == 1:
        p = np.array(
            [p[0], max(0.0, -p[0])]
        )  # a host with no drag of its own, or the least that keeps B_inspector >= 0
    if p.size != spec.n_params:
        raise ValueError(f"effect {name!r} takes {spec.n_params} parameters, got {p.size}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"effect {name!r}: parameters not finite: {p}")
    return p


class EffectSet(dict):
    """name -> parameter vector (np.ndarray), validated on entry."""

    def __init__(self, items=None, **kw):
        super().__init__()
        for k, v in dict(items or {}, **kw).items():
            self[k] = v

    def __setitem__(self, name, params):
        super().__setitem__(name, canonical(name, params))

    def update(self, other=(), **kw):
        for k, v in dict(other, **kw).items():
            self[k] = v

    def to_json(self) -> dict:
        return {k: [float(x) for x in v] for k, v in self.items()}


@dataclass
class Realisation:
    """The physical settings an EffectSet amounts to."""

    vehicle: Vehicle
    plant: PlantEffects | None
    profile: NoiseProfile
    c_imu_b: np.ndarray | None = None
    lever_arm_b_m: np.ndarray | None = None
    # The body-fixed point the pose sensor reports, from the true centre of
    # mass (a centre-of-mass offset moves the mass, not the camera's target).
    pose_point_b_m: np.ndarray | None = None
    occlusion: tuple | None = None
    camera_latency_s: float = 0.0
    imu_clock_rate: float = 1.0
    lens_k1: float = 0.0  # radial distortion of the camera the pipeline takes for a pinhole


def plant_effects(effects, pfx: PlantEffects | None = None) -> tuple:
    """(PlantEffects, any set): the plant-level physics of ``effects`` (mass
    depletion, host eccentricity, differential J2 and drag, a flexible mode,
    fuel slosh); the vehicle's own effects (thrusters, centre of mass) are
    the caller's."""
    pfx = pfx if pfx is not None else PlantEffects()
    e = {k: np.atleast_1d(np.asarray(v, float)) for k, v in effects.items()}
    on = False
    if "mass_depletion" in e:
        pfx.mass_flow_kgps_per_valve = float(e["mass_depletion"][0])
        on = True
    if "host_eccentricity" in e:
        pfx.host_eccentricity, pfx.host_true_anomaly0_rad = (float(x) for x in e["host_eccentricity"])
        on = True
    if "differential_j2" in e:
        pfx.j2 = float(e["differential_j2"][0])
        on = True
    if "differential_drag" in e:
        p = e["differential_drag"]
        pfx.diff_ballistic_m2pkg = float(p[0])
        pfx.host_ballistic_m2pkg = float(p[1]) if p.size > 1 else max(0.0, -float(p[0]))
        if pfx.diff_ballistic_m2pkg + pfx.host_ballistic_m2pkg < 0.0 or pfx.host_ballistic_m2pkg < 0.0:
            raise ValueError("differential_drag: B_host and B_inspector = dB + B_host must be >= 0")
        on = True
    if "flex_mode" in e:
        pfx.flex_freq_hz, pfx.flex_amplitude_rad = (float(x) for x in e["flex_mode"])
        on = True
    if "fuel_slosh" in e:
        pfx.slosh_mass_kg = float(e["fuel_slosh"][0])
        on = True
    return pfx, on


def realise(effects: EffectSet, vehicle: Vehicle, profile: NoiseProfile, seed: int) -> Realisation:
    """Physical settings of plant, vehicle and sensors for ``effects``.
    ``seed`` drives the effects' own randomness (which frames are occluded),
    apart from the scenario's streams so that everything else stays the same."""
    e = EffectSet(effects)
    veh = replace(
        vehicle,
        directions_b=vehicle.directions_b.copy(),
        thrust_scale=vehicle.thrust_scale.copy(),
        positions_b_m=vehicle.positions_b_m.copy(),
    )
    pfx = PlantEffects()
    plant_on = False
    if "thruster_misalignment" in e:
        phi = e["thruster_misalignment"].reshape(N_THRUSTERS, 3)
        veh.directions_b = np.array([rotmat(qexp(phi[i])) @ veh.directions_b[i] for i in range(N_THRUSTERS)])
    if "thrust_loss" in e:
        veh.thrust_scale = veh.thrust_scale * (1.0 - e["thrust_loss"])
    if "com_offset" in e:
        c = e["com_offset"]
        veh.positions_b_m = veh.positions_b_m - c  # thrust torques about the true centre of mass
        pfx.imu_offset_b_m = -c  # accelerometer at the body origin
        plant_on = True
    pfx, on = plant_effects(e, pfx)
    plant_on = plant_on or on
    prof = profile
    if "accel_bias" in e:
        prof = prof.with_(accel_bias_mps2=tuple(np.asarray(prof.accel_bias_mps2) + e["accel_bias"]))
    if "gyro_bias" in e:
        prof = prof.with_(gyro_bias_rps=tuple(np.asarray(prof.gyro_bias_rps) + e["gyro_bias"]))
    if "gyro_scale" in e:
        prof = prof.with_(gyro_scale=tuple(np.asarray(prof.gyro_scale) + e["gyro_scale"]))
    out = Realisation(veh, pfx if plant_on else None, prof)
    if "com_offset" in e:
        out.pose_point_b_m = -np.asarray(e["com_offset"], float)  # the pose reports the body origin
    if "imu_misalignment" in e:
        # IMU axes = body axes turned by Exp(phi): a body vector reads C(phi)^T v in IMU axes.
        out.c_imu_b = rotmat(qexp(e["imu_misalignment"])).T
    if "camera_lever_arm" in e:
        out.lever_arm_b_m = e["camera_lever_arm"].copy()
    if "led_occlusion" in e:
        bias, frac = e["led_occlusion"]
        out.occlusion = (
            float(bias),
            float(np.clip(frac, 0.0, 1.0)),
            np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x0CC1]),
        )
    if "camera_latency" in e:
        out.camera_latency_s = float(e["camera_latency"][0])
        if out.camera_latency_s < 0.0:
            raise ValueError("camera_latency must be >= 0 (the pose is captured before its time tag)")
    if "clock_drift" in e:
        out.imu_clock_rate = 1.0 + float(e["clock_drift"][0])
    if "lens_distortion" in e:
        out.lens_k1 = float(e["lens_distortion"][0])
    return out


def draw_effect_set(rng: np.random.Generator, name: str, scale: float) -> EffectSet:
    """One effect, drawn at ``scale`` times its min_detectable."""
    return EffectSet({name: EFFECTS[name].draw(rng, scale)})


def true_anomaly_after(e: float, f0: float, mean_anomaly_advance: float) -> float:
    """True anomaly of a Kepler orbit (eccentricity e) after the mean anomaly
    has advanced by ``mean_anomaly_advance`` from true anomaly f0."""
    beta = e / (1.0 + np.sqrt(1.0 - e * e))
    ecc0 = f0 - 2.0 * np.arctan2(beta * np.sin(f0), 1.0 + beta * np.cos(f0))
    mean = ecc0 - e * np.sin(ecc0) + mean_anomaly_advance
    ecc = mean
    for _ in range(50):
        d = (ecc - e * np.sin(ecc) - mean) / (1.0 - e * np.cos(ecc))
        ecc -= d
        if abs(d) < 1e-15:
            break
    return float(ecc + 2.0 * np.arctan2(beta * np.sin(ecc), 1.0 - beta * np.cos(ecc)))
