"""What a flight log says about the vehicle and sensors that flew it (format
version 2, docs/FLIGHT_LOG.md): the vehicle (mass, inertia, centre of mass,
each thruster), the IMU (rate, mounting, noise), the pose sensor (reference
point, clock offset, latency), the orbit, and the segments (where each run
starts and what it flies).

``resolve(description)`` checks every field, names the ones that are wrong
("vehicle.thrusters[3].direction_b: not a unit vector (norm 0.7)"), fills
what is missing from the bench's 3 kg inspector and says which defaults it
used, so an answer can name them. The diagnosis reads only the resolved
form (:class:`Resolved`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

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
class Thruster:
    position_b_m: np.ndarray
    direction_b: np.ndarray
    thrust_n: float
    min_on_time_s: float


@dataclass
class Segment:
    t_start_s: float
    t_end_s: float
    manoeuvre: str
    starts_at_rest: bool


@dataclass
class Resolved:
    """Every field the diagnosis uses, with the defaults filled in."""

    mass_kg: float
    inertia_kgm2: np.ndarray  # (3, 3)
    com_b_m: np.ndarray
    thrusters: list
    imu_rate_hz: float | None  # None: from the IMU time stamps
    imu_q_body_imu: np.ndarray  # rotates IMU-axis vectors into body axes
    imu_position_b_m: np.ndarray
    accel_sigma_mps2: float
    gyro_sigma_rps: float
    pose_reference_b_m: np.ndarray
    pose_time_offset_s: float  # added to the pose's capture time to put it on the IMU clock
    pose_latency_s: float  # known delay of the capture time stamp (subtracted)
    orbit_radius_m: float
    segments: list  # [Segment], empty: found from the data (version 1 rules)
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


def _short_repr(x) -> str:
    text = repr(x)
    return text if len(text) <= 60 else text[:57] + "..."


def _array(x):
    """``x`` as a float array, None when it is not a (nested) list of numbers."""
    if isinstance(x, (list, tuple)) and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) or isinstance(v, (list, tuple)) for v in x
    ):
        try:
            with np.errstate(over="ignore"):
                return np.asarray(x, dtype=float)
        except (ValueError, TypeError, OverflowError):
            return None
    return None


def _vec(x, n: int, where: str, bound: float | None = None) -> np.ndarray:
    a = _array(x)
    if a is None or a.shape != (n,):
        raise DescriptionError(f"{where}: expected {n} numbers, got {_short_repr(x)}")
    if not np.all(np.isfinite(a)):
        raise DescriptionError(f"{where}: not finite ({_short_repr(x)})")
    if bound is not None and np.linalg.norm(a) > bound:
        raise DescriptionError(f"{where}: {np.linalg.norm(a):.6g} m from the body origin, more than {bound:g} m")
    return a


def _num(x, where: str, lo: float | None = None, hi: float | None = None, strict_lo: bool = False) -> float:
    try:
        ok = not isinstance(x, bool) and isinstance(x, (int, float)) and math.isfinite(float(x))
    except OverflowError:  # an integer beyond float's range
        ok = False
    if not ok:
        raise DescriptionError(f"{where}: expected a finite number, got {_short_repr(x)}")
    v = float(x)
    if lo is not None and (v <= lo if strict_lo else v < lo):
        raise DescriptionError(f"{where}: {v!r} must be {'>' if strict_lo else '>='} {lo!r}")
    if hi is not None and v > hi:
        raise DescriptionError(f"{where}: {v!r} must be <= {hi!r}")
    return v


def _obj(d, where: str, known: tuple) -> dict:
    if d is None:
        return {}
    if not isinstance(d, dict):
        raise DescriptionError(f"{where}: expected an object, got {type(d).__name__}")
    unknown = sorted(set(d) - set(known))
    if unknown:
        raise DescriptionError(f"{where}.{str(unknown[0])[:40]}: unknown field (known: {', '.join(known)})")
    return d


def _inertia(x, where: str) -> np.ndarray:
    a = _array(x)
    if a is not None and a.shape == (3,):
        a = np.diag(a)
    if a is None or a.shape != (3, 3) or not np.all(np.isfinite(a)):
        raise DescriptionError(f"{where}: expected 3 principal moments or a 3x3 matrix [kg m^2], got {_short_repr(x)}")
    if not np.allclose(a, a.T, rtol=1e-9, atol=1e-12):
        raise DescriptionError(f"{where}: not symmetric")
    ev = np.linalg.eigvalsh(a)
    if ev[0] <= 0.0:
        raise DescriptionError(f"{where}: not positive definite (eigenvalues {ev.tolist()})")
    if ev[0] < INERTIA_KGM2[0] or ev[-1] > INERTIA_KGM2[1]:
        raise DescriptionError(
            f"{where}: principal moments {ev.tolist()} outside {INERTIA_KGM2[0]:g} to {INERTIA_KGM2[1]:g} kg m^2"
        )
    s = np.sort(ev)
    if s[0] + s[1] < s[2] * (1.0 - 1e-9):
        raise DescriptionError(
            f"{where}: breaks the triangle inequality of a rigid body (principal moments {s.tolist()})"
        )
    return a


def _thrusters(x, where: str) -> list:
    if not isinstance(x, list) or not 1 <= len(x) <= MAX_THRUSTERS:
        raise DescriptionError(f"{where}: expected a list of 1 to {MAX_THRUSTERS} thrusters")
    out = []
    for i, t in enumerate(x):
        w = f"{where}[{i}]"
        t = _obj(t, w, ("position_b_m", "direction_b", "thrust_n", "min_on_time_s"))
        for key in ("position_b_m", "direction_b", "thrust_n"):
            if key not in t:
                raise DescriptionError(f"{w}.{key}: missing")
        d = _vec(t["direction_b"], 3, f"{w}.direction_b")
        if abs(np.linalg.norm(d) - 1.0) > UNIT_TOL:
            raise DescriptionError(f"{w}.direction_b: not a unit vector (norm {np.linalg.norm(d):.6g})")
        out.append(
            Thruster(
                _vec(t["position_b_m"], 3, f"{w}.position_b_m", MAX_POSITION_M),
                d / np.linalg.norm(d),
                _num(t["thrust_n"], f"{w}.thrust_n", 0.0, THRUST_N, strict_lo=True),
                _num(t.get("min_on_time_s", 0.0), f"{w}.min_on_time_s", 0.0, MIN_ON_TIME_S),
            )
        )
    return out


def _segments(x, where: str) -> list:
    if not isinstance(x, list):
        raise DescriptionError(f"{where}: expected a list of segments")
    if not x:
        raise DescriptionError(f"{where}: an empty list (leave the field out to have the runs found from the data)")
    out = []
    for i, s in enumerate(x):
        w = f"{where}[{i}]"
        s = _obj(s, w, ("t_start_s", "t_end_s", "manoeuvre", "starts_at_rest"))
        for key in ("t_start_s", "t_end_s"):
            if key not in s:
                raise DescriptionError(f"{w}.{key}: missing")
        a = _num(s["t_start_s"], f"{w}.t_start_s", -MAX_STAMP_S, MAX_STAMP_S)
        b = _num(s["t_end_s"], f"{w}.t_end_s", -MAX_STAMP_S, MAX_STAMP_S)
        if b <= a:
            raise DescriptionError(f"{w}.t_end_s: {b!r} is not after t_start_s {a!r}")
        if out and a < out[-1].t_end_s:
            raise DescriptionError(f"{w}.t_start_s: {a!r} overlaps the previous segment (ends {out[-1].t_end_s!r})")
        m = s.get("manoeuvre", "other")
        if m not in MANOEUVRES:
            raise DescriptionError(f"{w}.manoeuvre: {m!r} is not one of {', '.join(MANOEUVRES)}")
        rest = s.get("starts_at_rest", True)
        if not isinstance(rest, bool):
            raise DescriptionError(f"{w}.starts_at_rest: expected true or false, got {rest!r}")
        out.append(Segment(a, b, m, rest))
    return out


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


_TOP = ("vehicle", "imu", "pose_sensor", "orbit", "segments")


def resolve(desc: dict | None, config: dict | None = None) -> Resolved:
    """The description with every default filled in and named. ``config``
    (version 1's free-form config_json) supplies the keys version 1 read:
    orbit_radius_m, noise.accel_sigma_mps2 / gyro_sigma_rps, vehicle.mass_kg /
    inertia_kgm2 / thrust_n."""
    desc = _obj(desc, "description", _TOP)
    config = config or {}
    base = bench_description()
    defaults = []
    veh = _obj(desc.get("vehicle"), "vehicle", ("mass_kg", "inertia_kgm2", "com_b_m", "thrusters", "envelope_m"))
    mass, inertia, com, thr = _resolve_vehicle(veh, config, base, defaults)
    rate, qbi, ipos, sig_a, sig_g, bias_a, bias_g = _resolve_imu(desc.get("imu"), config, base, com, defaults)
    pose = _obj(desc.get("pose_sensor"), "pose_sensor", ("reference_point_b_m", "time_offset_s", "latency_s"))
    pref = _vec(
        _pick(
            defaults, pose, "reference_point_b_m", "pose_sensor.reference_point_b_m", com.tolist(), "the centre of mass"
        ),
        3,
        "pose_sensor.reference_point_b_m",
        MAX_POSITION_M,
    )
    toff = _num(
        _pick(defaults, pose, "time_offset_s", "pose_sensor.time_offset_s", 0.0, "pose and IMU on one clock"),
        "pose_sensor.time_offset_s",
        -MAX_STAMP_S,
        MAX_STAMP_S,
    )
    lat = _num(
        _pick(defaults, pose, "latency_s", "pose_sensor.latency_s", 0.0, "capture times exact"),
        "pose_sensor.latency_s",
        0.0,
        MAX_LATENCY_S,
    )
    radius = _resolve_orbit(desc.get("orbit"), config, base, defaults)
    if "envelope_m" in veh:
        envelope = _num(veh["envelope_m"], "vehicle.envelope_m", 0.0, 100.0, strict_lo=True)
    else:
        pts = [t.position_b_m for t in thr] + [ipos, pref]
        envelope = 2.0 * max(float(np.linalg.norm(p)) for p in pts)
        defaults.append(
            f"vehicle.envelope_m = {envelope:.3g} (twice the farthest described point from the body origin)"
        )
    segs = _segments(desc["segments"], "segments") if "segments" in desc else []
    if "segments" not in desc:
        defaults.append(
            "segments = found from the data (a skipped IMU tick or a break in the pose stream starts a "
            "run; every run starts at rest; manoeuvres unknown)"
        )
    return Resolved(
        mass,
        inertia,
        com,
        thr,
        rate,
        qbi / np.linalg.norm(qbi),
        ipos,
        sig_a,
        sig_g,
        pref,
        toff,
        lat,
        radius,
        segs,
        envelope_m=envelope,
        accel_bias_stability_mps2=bias_a,
        gyro_bias_stability_rps=bias_g,
        defaults=defaults,
    )


def _pick(defaults: list, section: dict, key: str, where: str, fallback, why: str = "bench inspector"):
    """section[key], or the fallback, named in ``defaults`` with why."""
    if key in section:
        return section[key]
    defaults.append(f"{where} = {_short(fallback)} ({why})")
    return fallback


def _resolve_vehicle(veh: dict, config: dict, base: dict, defaults: list) -> tuple:
    """(mass, inertia, centre of mass, thrusters); what version 1's
    config_json stated fills a missing field and is not a default."""
    cveh = config.get("vehicle") if isinstance(config.get("vehicle"), dict) else {}
    bv = dict(base["vehicle"])
    for k in ("mass_kg", "inertia_kgm2"):  # version 1's config_json, where a log has no description
        if k in cveh:
            bv[k] = cveh[k]
    if "thrust_n" in cveh:
        bv["thrusters"] = [dict(t, thrust_n=cveh["thrust_n"]) for t in bv["thrusters"]]
    found = []
    mass = _num(_pick(found, veh, "mass_kg", "vehicle.mass_kg", bv["mass_kg"]), "vehicle.mass_kg", *MASS_KG)
    inertia = _inertia(
        _pick(found, veh, "inertia_kgm2", "vehicle.inertia_kgm2", bv["inertia_kgm2"]), "vehicle.inertia_kgm2"
    )
    com = _vec(_pick(found, veh, "com_b_m", "vehicle.com_b_m", bv["com_b_m"]), 3, "vehicle.com_b_m", MAX_POSITION_M)
    thr = _thrusters(
        _pick(found, veh, "thrusters", "vehicle.thrusters", bv["thrusters"], "bench inspector's 8 thrusters"),
        "vehicle.thrusters",
    )
    defaults.extend(x for x in found if x.split(" ")[0].split(".")[-1] not in cveh)
    _check_authority(mass, inertia, com, thr)
    return mass, inertia, com, thr


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


_IMU_FIELDS = (
    "rate_hz",
    "sample",
    "q_body_imu",
    "position_b_m",
    "accel_sigma_mps2",
    "gyro_sigma_rps",
    "accel_noise_density_mps2_rthz",
    "gyro_noise_density_rps_rthz",
    "accel_bias_stability_mps2",
    "gyro_bias_stability_rps",
)


def _resolve_imu(imu, config: dict, base: dict, com: np.ndarray, defaults: list) -> tuple:
    """(rate, q_body_imu, position, accel sigma, gyro sigma, accel and gyro
    bias stability)."""
    imu = _obj(imu, "imu", _IMU_FIELDS)
    rate = None
    if "rate_hz" in imu:
        rate = _num(imu["rate_hz"], "imu.rate_hz", *IMU_RATE_HZ)
    sample = imu.get("sample", "mean")
    if sample != "mean":
        raise DescriptionError(
            f"imu.sample: {sample!r} not supported: each sample must be the mean over the "
            "interval ending at its time stamp ('mean'), as delta-v / delta-angle IMUs report"
        )
    qbi = _vec(
        _pick(defaults, imu, "q_body_imu", "imu.q_body_imu", base["imu"]["q_body_imu"], "IMU axes = body axes"),
        4,
        "imu.q_body_imu",
    )
    if abs(np.linalg.norm(qbi) - 1.0) > 1e-6:
        raise DescriptionError(f"imu.q_body_imu: quaternion [w, x, y, z] norm {np.linalg.norm(qbi):.9g}, expected 1")
    ipos = _vec(
        _pick(defaults, imu, "position_b_m", "imu.position_b_m", com.tolist(), "at the centre of mass"),
        3,
        "imu.position_b_m",
        MAX_POSITION_M,
    )
    cnoise = config.get("noise") if isinstance(config.get("noise"), dict) else {}
    sig_a = _sigma(imu, cnoise, config, "accel", rate, base["imu"]["accel_sigma_mps2"], defaults)
    sig_g = _sigma(imu, cnoise, config, "gyro", rate, base["imu"]["gyro_sigma_rps"], defaults)
    bias_a = _num(
        _pick(
            defaults,
            imu,
            "accel_bias_stability_mps2",
            "imu.accel_bias_stability_mps2",
            0.0,
            "not stated: a constant accelerometer bias of any size is a gap",
        ),
        "imu.accel_bias_stability_mps2",
        0.0,
        1.0,
    )
    bias_g = _num(
        _pick(
            defaults,
            imu,
            "gyro_bias_stability_rps",
            "imu.gyro_bias_stability_rps",
            0.0,
            "not stated: a constant gyro bias of any size is a gap",
        ),
        "imu.gyro_bias_stability_rps",
        0.0,
        1.0,
    )
    return rate, qbi, ipos, sig_a, sig_g, bias_a, bias_g


def _resolve_orbit(orb, config: dict, base: dict, defaults: list) -> float:
    """The host's orbit radius [m]."""
    orb = _obj(orb, "orbit", ("radius_m", "altitude_m"))
    if "radius_m" in orb and "altitude_m" in orb:
        raise DescriptionError("orbit: give radius_m or altitude_m, not both")
    if "altitude_m" in orb:
        return EARTH_RADIUS_M + _num(orb["altitude_m"], "orbit.altitude_m", 100e3, 1e8)
    if "radius_m" in orb:
        return _num(orb["radius_m"], "orbit.radius_m", EARTH_RADIUS_M + 100e3, 1e8)
    if "orbit_radius_m" in config:
        return _num(config["orbit_radius_m"], "config_json.orbit_radius_m", EARTH_RADIUS_M + 100e3, 1e8)
    radius = base["orbit"]["radius_m"]
    defaults.append(f"orbit.radius_m = {radius:.0f} (circular, 500 km altitude)")
    return radius


def _sigma(imu: dict, cnoise: dict, config: dict, which: str, rate, fallback: float, defaults: list) -> float:
    unit = "mps2" if which == "accel" else "rps"
    lo, hi = ACCEL_SIGMA_MPS2 if which == "accel" else GYRO_SIGMA_RPS
    key, dens = f"{which}_sigma_{unit}", f"{which}_noise_density_{unit}_rthz"
    if key in imu and dens in imu:
        raise DescriptionError(f"imu: give {key} or {dens}, not both")
    if key in imu:
        return _num(imu[key], f"imu.{key}", lo, hi)
    if dens in imu:
        if rate is None:
            raise DescriptionError(f"imu.{dens}: needs imu.rate_hz (the per-sample sigma is density * sqrt(rate))")
        sigma = _num(imu[dens], f"imu.{dens}", 0.0, strict_lo=True) * math.sqrt(rate)
        if not lo <= sigma <= hi:
            raise DescriptionError(
                f"imu.{dens}: a per-sample sigma of {sigma:.6g} at {rate:g} Hz, outside {lo:g} to {hi:g}"
            )
        return sigma
    for src, name in ((cnoise, f"config_json.noise.{key}"), (config, f"config_json.{key}")):
        if key in src:
            return _num(src[key], name, lo, hi)
    defaults.append(f"imu.{key} = {fallback:.6g} (bench IMU)")
    return fallback


def _short(x) -> str:
    if isinstance(x, list) and len(x) > 3:
        return f"[{len(x)} entries]"
    if isinstance(x, float):
        return f"{x:.6g}"
    return str(x)
