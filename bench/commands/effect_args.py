"""The `--effects` option of `proxops simulate`: a JSON object, effect name
-> parameters (docs/EFFECTS.md). Every effect must be one the engine
simulates; each value a number or a list of numbers, finite, as many as the
effect takes on the described vehicle (thrust_loss: 1 or one per thruster;
thruster_misalignment: 3 per thruster, flat or one list per thruster) and
within its physical bound (bench/sim/effects.py, ``max_size_for``). A
mistake is refused in one line naming the effect, before anything is
simulated or written."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

# Parameters that cannot be negative, by index: a propellant flow, a delay,
# an eccentricity, J2, a slosh mass, a mode's frequency, the host's ballistic
# coefficient.
NONNEGATIVE = {
    "mass_depletion": (0,),
    "camera_latency": (0,),
    "host_eccentricity": (0,),
    "differential_j2": (0,),
    "fuel_slosh": (0,),
    "flex_mode": (0,),
    "differential_drag": (1,),
}
MAX_THRUST_LOSS = 1.0  # a thruster's loss beyond 1 would reverse its thrust
PER_THRUSTER = ("thrust_loss", "thruster_misalignment")


MAX_EFFECTS_BYTES = 1 << 20  # far beyond any list of effects with a parameter per thruster
MAX_INT_DIGITS = 18


def _int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_INT_DIGITS:
        raise ValueError(f"an integer of {len(text.lstrip('-'))} digits")
    return int(text)


def read_effects(text: str) -> dict:
    """The option's JSON object (given inline or as a file holding it)."""
    if not text.lstrip().startswith("{"):
        src = Path(text)
        if src.is_dir():
            raise ValueError(f"--effects {text}: a folder, expected a JSON object or a file holding one")
        if src.exists():
            try:
                if src.stat().st_size > MAX_EFFECTS_BYTES:
                    raise ValueError(f"--effects {text}: larger than {MAX_EFFECTS_BYTES >> 20} MiB")
                text = src.read_text()
            except (OSError, UnicodeDecodeError) as exc:
                raise ValueError(f"--effects {text}: unreadable ({type(exc).__name__})") from None
    if len(text) > MAX_EFFECTS_BYTES:
        raise ValueError(f"--effects: longer than {MAX_EFFECTS_BYTES >> 20} MiB")
    try:
        eff = json.loads(text, parse_int=_int)
    except RecursionError:
        raise ValueError("--effects: not JSON (nested too deeply)") from None
    except ValueError as exc:
        raise ValueError(f"--effects: not JSON ({str(exc)[:120]})") from None
    if not isinstance(eff, dict):
        raise ValueError("--effects: expected a JSON object, name -> parameters")
    return eff


def _short(value) -> str:
    try:
        text = json.dumps(value) if not isinstance(value, float) else repr(value)
    except (ValueError, RecursionError):
        text = type(value).__name__
    return text if len(text) <= 60 else text[:57] + "..."


def _numbers(value, where: str, rows_of: int | None = None) -> np.ndarray:
    """The value as a flat float vector; ``rows_of``: a list of lists of that
    many numbers is taken too (one row per thruster)."""
    flat = value if isinstance(value, list) else [value]
    if rows_of is not None and flat and all(isinstance(v, list) for v in flat):
        if any(len(v) != rows_of for v in flat):
            raise ValueError(f"{where}: expected rows of {rows_of} numbers, got {_short(value)}")
        flat = [x for v in flat for x in v]
    if not flat or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in flat):
        raise ValueError(f"{where}: expected a number or a list of numbers, got {_short(value)}")
    try:
        p = np.array(flat, dtype=float)
    except OverflowError:  # an integer beyond float's range
        p = np.array([np.inf])
    if not np.all(np.isfinite(p)):
        raise ValueError(f"{where}: not finite ({_short(value)})")
    return p


def _count_ok(name: str, p: np.ndarray, k: int, spec, where: str) -> None:
    """As many values as the effect takes on a vehicle of k thrusters."""
    if name == "thrust_loss":
        sizes, what = (1, k), f"1 value or {k} (one per thruster of the described vehicle)"
    elif name == "thruster_misalignment":
        sizes, what = (3 * k,), f"{3 * k} values (a rotation vector per thruster of the {k} described)"
    elif name == "differential_drag":
        sizes, what = (1, 2), "1 or 2 values (" + ", ".join(spec.param_names) + ")"
    else:
        sizes, what = (spec.n_params,), f"{spec.n_params} values (" + ", ".join(spec.param_names) + ")"
    if p.size not in sizes:
        raise ValueError(f"{where}: expected {what}, got {p.size}")


def _size(name: str, p: np.ndarray, spec) -> float:
    """The effect's size as docs/EFFECTS.md measures it, on any vehicle."""
    if name == "thrust_loss":
        return float(np.sqrt(np.mean(p**2)))
    if name == "thruster_misalignment":
        return float(np.sqrt(np.mean(np.sum(p.reshape(-1, 3) ** 2, axis=1))))
    return float(spec.size(p))


def check_effects(effects: dict, desc, known: tuple) -> dict:
    """``effects`` checked for the described vehicle (a resolved description)
    and an engine that simulates ``known``; returned unchanged."""
    from bench.sim.effects import EFFECTS, max_size_for

    for name, value in effects.items():
        where = f"--effects: {str(name)[:40]}"
        if name not in known:
            raise ValueError(f"{where}: not an effect this engine simulates (it simulates: {', '.join(known)})")
        spec = EFFECTS[name]
        p = _numbers(value, where, rows_of=3 if name == "thruster_misalignment" else None)
        _count_ok(name, p, desc.n_thrusters, spec, where)
        for i in NONNEGATIVE.get(name, ()):
            if i < p.size and p[i] < 0.0:
                raise ValueError(f"{where}: {spec.param_names[i]} = {p[i]:g} must be >= 0")
        if name == "thrust_loss" and np.any(np.abs(p) > MAX_THRUST_LOSS):
            raise ValueError(f"{where}: {p[np.argmax(np.abs(p))]:g} beyond the physical bound: |loss| <= 1")
        if name == "differential_drag" and p.size == 2 and p[0] + p[1] < 0.0:
            raise ValueError(f"{where}: dB + B_host = {p[0] + p[1]:g}, the inspector's own, must be >= 0")
        with np.errstate(over="ignore", invalid="ignore"):  # a size of 1e300 squared: refused below, not warned
            size, bound = _size(name, p, spec), max_size_for(name, desc)
        if not math.isfinite(size) or size > bound:
            raise ValueError(f"{where}: size {size:.3g} {spec.unit} beyond its physical bound {bound:.3g} {spec.unit}")
    return effects
