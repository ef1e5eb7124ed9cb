"""What a flight log says about the vehicle and sensors that flew it (format
version 2, docs/FLIGHT_LOG.md): the vehicle (mass, inertia, centre of mass,
each thruster), the IMU (rate, mounting, noise), the pose sensor (reference
point, clock offset, latency), the orbit, and the segments (where each run
starts and what it flies).

The pydantic models below (:class:`Description`) are the schema.
``resolve(description)`` validates it, names the first wrong field in one
line ("vehicle.thrusters[3].direction_b: not a unit vector (norm 0.7)"),
fills what is missing from the bench's 3 kg inspector and says which
defaults it used, so an answer can name them. The diagnosis reads only the
resolved form (:class:`Resolved`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Annotated, Literal, Union, get_args, get_origin

import numpy as np
from pydantic import AfterValidator, BaseModel, Field, TypeAdapter, ValidationError, WrapValidator, model_validator

from bench.sim import vehicle as bench_vehicle
from bench.sim.flight_log_bounds import MAX_STAMP_S

EARTH_RADIUS_M = 6378137.0
MU_EARTH = 3.986004418e14
MANOEUVRES = ("docking", "characterisation", "other")
MAX_THRUSTERS = 32
UNIT_TOL = 1e-3
G0_MPS2 = 9.80665
# Below the specific impulse of any thruster a small spacecraft flies (cold
# gas 45 to 75 s): no valve expels propellant faster than thrust / (g0 Isp).
ISP_MIN_S = 20.0
# Physical bounds (docs/FLIGHT_LOG.md, "Bounds"): a value outside them is
# refused, so no description can drive the arithmetic to overflow, underflow
# or a calibration that never ends.
MASS_KG = (0.01, 1e5)
INERTIA_KGM2 = (1e-8, 1e8)  # principal moments
THRUST_N = 1e3
MIN_ON_TIME_S = 10.0
MAX_POSITION_M = 100.0  # any described point from the body origin (as vehicle.envelope_m)
IMU_RATE_HZ = (0.01, 1e4)
# Noise floors far below any IMU (a noise-free simulation states 1e-15):
# they keep sigma^2 and the whitened residuals within float64.
ACCEL_SIGMA_MPS2 = (1e-20, 100.0)
GYRO_SIGMA_RPS = (1e-20, 10.0)
MAX_LATENCY_S = 60.0
# What the thrusters can do to the vehicle: all of them together accelerate
# it by at most MAX_ACCEL_MPS2, one of them turns it by at most
# MAX_ANGULAR_ACCEL_RPS2 about its weakest axis. Far beyond a small
# spacecraft's cold gas (the bench inspector: 0.05 m/s^2 and 0.18 rad/s^2;
# random vehicles up to 0.34 and 0.9); beyond them the simulated flights of
# the calibration made for the log leave the range of finite numbers.
MAX_ACCEL_MPS2 = 10.0
MAX_ANGULAR_ACCEL_RPS2 = 10.0


class DescriptionError(ValueError):
    """A description that breaks the contract; the message names the field."""


@dataclass
class Resolved:
    """Every field the diagnosis uses, with the defaults filled in."""

    mass_kg: float
    inertia_kgm2: np.ndarray  # (3, 3)
    com_b_m: np.ndarray
    thrusters: list  # [ThrusterDesc]
    imu_rate_hz: float | None  # None: from the IMU time stamps
    imu_q_body_imu: np.ndarray  # rotates IMU-axis vectors into body axes
    imu_position_b_m: np.ndarray
    accel_sigma_mps2: float
    gyro_sigma_rps: float
    pose_reference_b_m: np.ndarray
    pose_time_offset_s: float  # added to the pose's capture time to put it on the IMU clock
    pose_latency_s: float  # known delay of the capture time stamp (subtracted)
    orbit_radius_m: float
    segments: list  # [SegmentDesc], empty: found from the data (version 1 rules)
    # The vehicle's largest dimension: no lever arm on it can be longer.
    envelope_m: float = 0.0
    # 1-sigma size of an IMU bias that is not a defect (0: any bias is a gap).
    accel_bias_stability_mps2: float = 0.0
    gyro_bias_stability_rps: float = 0.0
    defaults: list = field(default_factory=list)  # "imu.accel_sigma_mps2 = 0.001667 (bench IMU)", ...

    @property
    def n_thrusters(self) -> int:
        return len(self.thrusters)

    @property
    def max_mass_flow_kgps(self) -> float:
        """The fastest any one valve can expel propellant (kg/s): its thrust at ISP_MIN_S."""
        return max(t.thrust_n for t in self.thrusters) / (G0_MPS2 * ISP_MIN_S)

    @property
    def mean_motion_radps(self) -> float:
        return math.sqrt(MU_EARTH / self.orbit_radius_m**3)

    def vehicle(self) -> bench_vehicle.Vehicle:
        """The bench's Vehicle about the centre of mass (thruster positions
        relative to it)."""
        pos = np.array([t.position_b_m for t in self.thrusters]) - self.com_b_m
        dirs = np.array([t.direction_b for t in self.thrusters])
        return bench_vehicle.Vehicle(
            mass_kg=self.mass_kg,
            inertia_kgm2=self.inertia_kgm2.copy(),
            thrust_n=np.array([t.thrust_n for t in self.thrusters]),
            positions_b_m=pos,
            directions_b=dirs,
            thrust_scale=np.ones(len(self.thrusters)),
        )

    def manoeuvres(self) -> list:
        return sorted({s.manoeuvre for s in self.segments})


# --- The schema: pydantic models; _message() words their errors ---


def _number(lo: float | None = None, hi: float | None = None, above: float | None = None):
    """A finite number (not a boolean or a string), >= lo (> above) and <= hi."""
    return Annotated[float, Field(strict=True, allow_inf_nan=False, ge=lo, gt=above, le=hi)]


def _short_repr(x) -> str:
    text = repr(x)
    return text if len(text) <= 60 else text[:57] + "..."


def _worded(word, *kinds) -> WrapValidator:
    """pydantic's errors of a value as one, worded ``word`` ("{!r}": the value) or ``word(value, errors)``;
    with ``kinds``, only the value's own errors of those types (its items' pass through)."""

    def wrap(x, handler):
        try:
            return handler(x)
        except ValidationError as e:
            errs = e.errors()
            if kinds and not any(not err["loc"] and err["type"] in kinds for err in errs):
                raise
            raise ValueError(word(x, errs) if callable(word) else word.format(x)) from None

    return WrapValidator(wrap)


def _vector(n: int, bad=lambda norm: False, text: str = ""):
    """n finite numbers as a float array, named as a whole when wrong; refused when bad(norm), worded text."""

    def word(x, errs) -> str:
        if isinstance(x, (list, tuple)) and len(x) == n and all(e["type"] == "finite_number" for e in errs):
            return f"not finite ({_short_repr(x)})"
        return f"expected {n} numbers, got {_short_repr(x)}"

    def parse(v: list) -> np.ndarray:
        if bad(np.linalg.norm(v)):
            raise ValueError(text.format(np.linalg.norm(v)))
        return np.asarray(v)

    return Annotated[list[_number()], Field(min_length=n, max_length=n), _worded(word), AfterValidator(parse)]


def _rigid_body(x: list) -> np.ndarray:
    """The 3x3 matrix of a rigid body's inertia (3 principal moments: its diagonal)."""
    a = np.asarray(x, dtype=float)
    a = np.diag(a) if a.ndim == 1 else a
    if not np.allclose(a, a.T, rtol=1e-9, atol=1e-12):
        raise ValueError("not symmetric")
    ev = np.linalg.eigvalsh(a)
    if ev[0] <= 0.0:
        raise ValueError(f"not positive definite (eigenvalues {ev.tolist()})")
    if ev[0] < INERTIA_KGM2[0] or ev[-1] > INERTIA_KGM2[1]:
        raise ValueError(f"principal moments {ev.tolist()} outside {INERTIA_KGM2[0]:g} to {INERTIA_KGM2[1]:g} kg m^2")
    s = np.sort(ev)
    if s[0] + s[1] < s[2] * (1.0 - 1e-9):
        raise ValueError(f"breaks the triangle inequality of a rigid body (principal moments {s.tolist()})")
    return a


_THREE = Annotated[list[_number()], Field(min_length=3, max_length=3)]
Inertia = Annotated[
    Union[_THREE, Annotated[list[_THREE], Field(min_length=3, max_length=3)]],
    _worded(lambda x, _: f"expected 3 principal moments or a 3x3 matrix [kg m^2], got {_short_repr(x)}"),
    AfterValidator(_rigid_body),
]
Position = _vector(3, lambda n: n > MAX_POSITION_M, f"{{:.6g}} m from the body origin, more than {MAX_POSITION_M:g} m")
Direction = Annotated[
    _vector(3, lambda n: abs(n - 1.0) > UNIT_TOL, "not a unit vector (norm {:.6g})"),
    AfterValidator(lambda d: d / np.linalg.norm(d)),
]
Quaternion = _vector(4, lambda n: abs(n - 1.0) > 1e-6, "quaternion [w, x, y, z] norm {:.9g}, expected 1")
Stamp = _number(-MAX_STAMP_S, MAX_STAMP_S)
AccelSigma = _number(*ACCEL_SIGMA_MPS2)
GyroSigma = _number(*GYRO_SIGMA_RPS)
OrbitRadius = _number(EARTH_RADIUS_M + 100e3, 1e8)


class _Section(BaseModel, extra="forbid"):
    """An object of the description: unknown fields refused, null read as {}."""

    @model_validator(mode="before")
    @classmethod
    def _null_is_empty(cls, data):
        return {} if data is None else data


class ThrusterDesc(_Section):
    position_b_m: Position
    direction_b: Direction  # force on the vehicle (opposite the exhaust), made a unit vector
    thrust_n: _number(above=0.0, hi=THRUST_N)
    min_on_time_s: _number(0.0, MIN_ON_TIME_S) = 0.0


class VehicleDesc(_Section):
    mass_kg: _number(*MASS_KG) = None
    inertia_kgm2: Inertia = None  # about the centre of mass, in body axes
    com_b_m: Position = None
    thrusters: Annotated[
        list[ThrusterDesc],
        Field(min_length=1, max_length=MAX_THRUSTERS),
        _worded(f"expected a list of 1 to {MAX_THRUSTERS} thrusters", "list_type", "too_short", "too_long"),
    ] = None
    envelope_m: _number(above=0.0, hi=MAX_POSITION_M) = None


class ImuDesc(_Section):
    rate_hz: _number(*IMU_RATE_HZ) = None  # left out: from the IMU time stamps
    sample: Annotated[
        Literal["mean"],
        _worded(
            "{!r} not supported: each sample must be the mean over the interval ending at its time stamp ('mean'), "
            "as delta-v / delta-angle IMUs report"
        ),
    ] = "mean"
    q_body_imu: Quaternion = None  # [w, x, y, z]: IMU-axis vectors into body axes
    position_b_m: Position = None
    accel_sigma_mps2: AccelSigma = None
    gyro_sigma_rps: GyroSigma = None
    accel_noise_density_mps2_rthz: _number(above=0.0) = None
    gyro_noise_density_rps_rthz: _number(above=0.0) = None
    accel_bias_stability_mps2: _number(0.0, 1.0) = None
    gyro_bias_stability_rps: _number(0.0, 1.0) = None


class PoseSensorDesc(_Section):
    reference_point_b_m: Position = None
    time_offset_s: Stamp = None  # added to the capture times to put them on the IMU clock
    latency_s: _number(0.0, MAX_LATENCY_S) = None


class OrbitDesc(_Section):
    radius_m: OrbitRadius = None
    altitude_m: _number(100e3, 1e8) = None

    @model_validator(mode="before")
    @classmethod
    def _one_form(cls, data):
        if isinstance(data, dict) and {"radius_m", "altitude_m"} <= data.keys():
            raise ValueError("give radius_m or altitude_m, not both")
        return data


class SegmentDesc(_Section):
    t_start_s: Stamp  # IMU clock
    t_end_s: Stamp
    manoeuvre: Annotated[Literal[MANOEUVRES], _worded(f"{{!r}} is not one of {', '.join(MANOEUVRES)}")] = "other"
    starts_at_rest: bool = Field(True, strict=True)


class Description(_Section):
    """A flight log's description_json; what is left out (None) takes its
    default in resolve(), which names it."""

    vehicle: VehicleDesc = Field(default_factory=VehicleDesc)
    imu: ImuDesc = Field(default_factory=ImuDesc)
    pose_sensor: PoseSensorDesc = Field(default_factory=PoseSensorDesc)
    orbit: OrbitDesc = Field(default_factory=OrbitDesc)
    segments: Annotated[
        list[SegmentDesc],
        Field(min_length=1),
        _worded("expected a list of segments", "list_type"),
        _worded("an empty list (leave the field out to have the runs found from the data)", "too_short"),
    ] = None  # left out: the runs are found from the data (version 1 rules)


# pydantic's error types in the description's words (the value, the error's context).
_WORDS = {
    "value_error": lambda x, ctx: str(ctx["error"]),  # a check's own words
    "missing": lambda x, ctx: "missing",
    "model_type": lambda x, ctx: f"expected an object, got {type(x).__name__}",
    "float_type": lambda x, ctx: f"expected a finite number, got {_short_repr(x)}",
    "finite_number": lambda x, ctx: f"expected a finite number, got {_short_repr(x)}",
    "greater_than_equal": lambda x, ctx: f"{float(x)!r} must be >= {ctx['ge']!r}",
    "greater_than": lambda x, ctx: f"{float(x)!r} must be > {ctx['gt']!r}",
    "less_than_equal": lambda x, ctx: f"{float(x)!r} must be <= {ctx['le']!r}",
    "bool_type": lambda x, ctx: f"expected true or false, got {x!r}",
}
_UNKNOWN = ("extra_forbidden", "invalid_key")  # a key no field has; a key that is no string


def _path(root: str, loc) -> str:
    for key in loc:
        root += f"[{key}]" if isinstance(key, int) else f".{key}" if root else str(key)
    return root or "description"


def _section_at(loc) -> type:
    """The model of the object at ``loc`` in a Description."""
    model = Description
    for key in (k for k in loc if isinstance(k, str)):
        model = model.model_fields[key].annotation
        model = get_args(model)[0] if get_origin(model) is list else model
    return model


def _message(errors: list, root: str = "") -> str:
    """pydantic's first error as one line, ``field.path: what is wrong``; an object's unknown
    fields come before anything inside it, so a misspelt key is what is named."""
    unknown = sorted((x for x in errors if x["type"] in _UNKNOWN), key=lambda x: (len(x["loc"]), str(x["loc"])))
    e = next((x for x in unknown if x["loc"][:-1] == errors[0]["loc"][: len(x["loc"]) - 1]), errors[0])
    loc, ctx = e["loc"], e.get("ctx") or {}
    if e["type"] in _UNKNOWN:
        known = ", ".join(_section_at(loc[:-1]).model_fields)
        return f"{_path(root, loc[:-1])}.{str(loc[-1])[:40]}: unknown field (known: {known})"
    word = _WORDS.get(e["type"], lambda x, ctx: e["msg"])
    return f"{_path(root, loc)}: {word(e['input'], ctx)}"


def _validated(validate, value, root: str = ""):
    try:
        return validate(value)
    except ValidationError as e:
        raise DescriptionError(_message(e.errors(), root)) from None


_ACCEPT = {"accel": TypeAdapter(AccelSigma), "gyro": TypeAdapter(GyroSigma), "orbit": TypeAdapter(OrbitRadius)}


# --- Resolving: defaults named, version 1's config_json read ---


def bench_description(n_thrusters_used: int | None = None) -> dict:
    """The bench's 3 kg inspector, bench IMU and pose sensor, written as a
    description (what version-1 logs and missing fields default to)."""
    v = bench_vehicle.Vehicle()
    return {
        "vehicle": {
            "mass_kg": v.mass_kg,
            "inertia_kgm2": np.diag(v.inertia_kgm2).tolist(),
            "com_b_m": [0.0, 0.0, 0.0],
            "thrusters": [
                {
                    "position_b_m": p.tolist(),
                    "direction_b": d.tolist(),
                    "thrust_n": float(v.thrust_n),
                    "min_on_time_s": 0.0,
                }
                for p, d in zip(v.positions_b_m, v.directions_b)
            ],
        },
        "imu": {
            "q_body_imu": [1.0, 0.0, 0.0, 0.0],
            "position_b_m": [0.0, 0.0, 0.0],
            "accel_sigma_mps2": 0.25 * float(v.thrust_n) / v.mass_kg,
            "gyro_sigma_rps": 0.005,
        },
        "pose_sensor": {"reference_point_b_m": [0.0, 0.0, 0.0], "time_offset_s": 0.0, "latency_s": 0.0},
        "orbit": {"radius_m": EARTH_RADIUS_M + 500e3},
    }


def resolve(desc: dict | None, config: dict | None = None) -> Resolved:
    """The description with every default filled in and named. ``config``
    (version 1's free-form config_json) supplies the keys version 1 read:
    orbit_radius_m, noise.accel_sigma_mps2 / gyro_sigma_rps, vehicle.mass_kg /
    inertia_kgm2 / thrust_n."""
    config = config or {}
    defaults = []
    d = _validated(Description.model_validate, _vehicle_filled(desc, config, defaults))
    veh, imu, pose = d.vehicle, d.imu, d.pose_sensor
    inertia, com, thr = veh.inertia_kgm2, veh.com_b_m, veh.thrusters
    _check_authority(veh.mass_kg, inertia, com, thr)
    qbi = _pick(defaults, imu, "imu.q_body_imu", [1.0, 0.0, 0.0, 0.0], "IMU axes = body axes")
    ipos = _pick(defaults, imu, "imu.position_b_m", com.tolist(), "at the centre of mass")
    bench_imu = bench_description()["imu"]
    sig_a = _sigma(imu, config, "accel", bench_imu["accel_sigma_mps2"], defaults)
    sig_g = _sigma(imu, config, "gyro", bench_imu["gyro_sigma_rps"], defaults)
    why = "not stated: a constant {} bias of any size is a gap"
    bias_a = _pick(defaults, imu, "imu.accel_bias_stability_mps2", 0.0, why.format("accelerometer"))
    bias_g = _pick(defaults, imu, "imu.gyro_bias_stability_rps", 0.0, why.format("gyro"))
    pref = _pick(defaults, pose, "pose_sensor.reference_point_b_m", com.tolist(), "the centre of mass")
    toff = _pick(defaults, pose, "pose_sensor.time_offset_s", 0.0, "pose and IMU on one clock")
    lat = _pick(defaults, pose, "pose_sensor.latency_s", 0.0, "capture times exact")
    radius = _orbit_radius(d.orbit, config, defaults)
    if "envelope_m" in veh.model_fields_set:
        envelope = veh.envelope_m
    else:
        pts = [t.position_b_m for t in thr] + [ipos, pref]
        envelope = 2.0 * max(float(np.linalg.norm(p)) for p in pts)
        defaults.append(
            f"vehicle.envelope_m = {envelope:.3g} (twice the farthest described point from the body origin)"
        )
    _check_order(d.segments or [])
    if "segments" not in d.model_fields_set:
        defaults.append(
            "segments = found from the data (a skipped IMU tick or a break in the pose stream starts a "
            "run; every run starts at rest; manoeuvres unknown)"
        )
    vehicle = (veh.mass_kg, inertia, com, thr)
    sensors = (imu.rate_hz, qbi / np.linalg.norm(qbi), ipos, sig_a, sig_g, pref, toff, lat)
    return Resolved(*vehicle, *sensors, radius, d.segments or [], envelope, bias_a, bias_g, defaults)


def _pick(defaults: list, section: BaseModel, where: str, fallback, why: str = "bench inspector"):
    """The section's field ``where`` names, or the fallback, named in ``defaults`` with why."""
    key = where.split(".")[-1]
    if key in section.model_fields_set:
        return getattr(section, key)
    defaults.append(f"{where} = {_short(fallback)} ({why})")
    return np.asarray(fallback, dtype=float) if isinstance(fallback, list) else fallback


def _vehicle_filled(desc, config: dict, defaults: list):
    """``desc`` with the vehicle fields it leaves out filled in before it is
    validated: mass_kg, inertia_kgm2 and thrust_n from version 1's
    config_json (a wrong one is named as the field it fills; not a default),
    the rest from the bench inspector, named in ``defaults``."""
    desc = {} if desc is None else desc
    veh = desc.get("vehicle") if isinstance(desc, dict) else None
    if not isinstance(desc, dict) or not isinstance(veh, (dict, type(None))):
        return desc  # the model names what is wrong
    cveh = config.get("vehicle") if isinstance(config.get("vehicle"), dict) else {}
    bench, stated = bench_description()["vehicle"], {k: cveh[k] for k in ("mass_kg", "inertia_kgm2") if k in cveh}
    if "thrust_n" in cveh:
        bench["thrusters"] = [dict(t, thrust_n=cveh["thrust_n"]) for t in bench["thrusters"]]
    veh = dict(veh or {})
    for key in (k for k in bench if k not in veh):
        veh[key] = stated.get(key, bench[key])
        why = "bench inspector's 8 thrusters" if key == "thrusters" else "bench inspector"
        if key not in stated:
            defaults.append(f"vehicle.{key} = {_short(bench[key])} ({why})")
    return dict(desc, vehicle=veh)


def _check_authority(mass: float, inertia: np.ndarray, com: np.ndarray, thr: list) -> None:
    """Refuse thrusters too strong for the vehicle described (MAX_ACCEL_MPS2,
    MAX_ANGULAR_ACCEL_RPS2): a mistaken unit or a missing factor, not a
    spacecraft whose flight can be simulated."""
    accel = sum(t.thrust_n for t in thr) / mass
    if accel > MAX_ACCEL_MPS2:
        raise DescriptionError(
            f"vehicle.mass_kg: {mass:.6g} kg with {sum(t.thrust_n for t in thr):.6g} N of thrust accelerates at "
            f"{accel:.3g} m/s^2, more than {MAX_ACCEL_MPS2:g}"
        )
    weakest = float(np.linalg.eigvalsh(inertia)[0])
    for i, t in enumerate(thr):
        torque = float(np.linalg.norm(np.cross(t.position_b_m - com, t.direction_b))) * t.thrust_n
        if torque / weakest > MAX_ANGULAR_ACCEL_RPS2:
            raise DescriptionError(
                f"vehicle.thrusters[{i}]: its torque of {torque:.3g} N m turns the vehicle at "
                f"{torque / weakest:.3g} rad/s^2 about its weakest axis ({weakest:.3g} kg m^2), more than "
                f"{MAX_ANGULAR_ACCEL_RPS2:g}"
            )


def _check_order(segments: list) -> None:
    """Each segment ends after it starts, and starts after the one before it ends."""
    for i, sg in enumerate(segments):
        if sg.t_end_s <= sg.t_start_s:
            raise DescriptionError(f"segments[{i}].t_end_s: {sg.t_end_s!r} is not after t_start_s {sg.t_start_s!r}")
        if i and sg.t_start_s < segments[i - 1].t_end_s:
            end = segments[i - 1].t_end_s
            raise DescriptionError(
                f"segments[{i}].t_start_s: {sg.t_start_s!r} overlaps the previous segment (ends {end!r})"
            )


def _orbit_radius(orbit: OrbitDesc, config: dict, defaults: list) -> float:
    """The host's orbit radius [m]."""
    if orbit.altitude_m is not None:
        return EARTH_RADIUS_M + orbit.altitude_m
    if orbit.radius_m is not None:
        return orbit.radius_m
    if "orbit_radius_m" in config:
        return _validated(_ACCEPT["orbit"].validate_python, config["orbit_radius_m"], "config_json.orbit_radius_m")
    radius = EARTH_RADIUS_M + 500e3
    defaults.append(f"orbit.radius_m = {radius:.0f} (circular, 500 km altitude)")
    return radius


_NOISE = {
    "accel": ("accel_sigma_mps2", "accel_noise_density_mps2_rthz", ACCEL_SIGMA_MPS2),
    "gyro": ("gyro_sigma_rps", "gyro_noise_density_rps_rthz", GYRO_SIGMA_RPS),
}


def _sigma(imu: ImuDesc, config: dict, which: str, fallback: float, defaults: list) -> float:
    """The per-sample sigma: stated, from the noise density, from version
    1's config_json, or the bench IMU's (named in ``defaults``)."""
    key, density, (lo, hi) = _NOISE[which]
    given = imu.model_fields_set
    if key in given and density in given:
        raise DescriptionError(f"imu: give {key} or {density}, not both")
    if key in given:
        return getattr(imu, key)
    if density in given:
        if imu.rate_hz is None:
            raise DescriptionError(f"imu.{density}: needs imu.rate_hz (the per-sample sigma is density * sqrt(rate))")
        sigma = getattr(imu, density) * math.sqrt(imu.rate_hz)
        if not lo <= sigma <= hi:
            raise DescriptionError(
                f"imu.{density}: a per-sample sigma of {sigma:.6g} at {imu.rate_hz:g} Hz, outside {lo:g} to {hi:g}"
            )
        return sigma
    noise = config.get("noise") if isinstance(config.get("noise"), dict) else {}
    for src, name in ((noise, f"config_json.noise.{key}"), (config, f"config_json.{key}")):
        if key in src:
            return _validated(_ACCEPT[which].validate_python, src[key], name)
    defaults.append(f"imu.{key} = {fallback:.6g} (bench IMU)")
    return fallback


def _short(x) -> str:
    if isinstance(x, list) and len(x) > 3:
        return f"[{len(x)} entries]"
    if isinstance(x, float):
        return f"{x:.6g}"
    return str(x)
