"""What a null calibration given with `proxops diagnose --calibration FILE`
must hold before the diagnosis trusts its thresholds.

A file of the wrong shape must not turn into "no gap": ``{}``, a threshold
that is missing, NaN, raised above what the file's own null runs give, or a
calibration made by another version of the statistics is refused with one
line naming the field. Two kinds are accepted:

- made for one log (``for_log``: bench/gap/log_null.py): of this code's
  calibration VERSION, with a SHA-256 fingerprint, each threshold the tail
  threshold of its null values (``log_null.unusable``); the fingerprint is
  then checked against the log (``log_null.check_supplied``);
- a committed calibration of the bench's (bench/gap/null.py, or the Frechet
  tail of bench/campaigns/gap/validate_vehicle.py): each threshold the one its null
  values give by the file's method, and the vehicle checked against the log.
"""

from __future__ import annotations

import math
import re

import numpy as np

FINGERPRINT = re.compile(r"[0-9a-f]{64}")


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _finite_list(cal: dict, key: str, runs: int) -> str | None:
    vals = cal.get(key)
    if not isinstance(vals, list) or not vals:
        return f"{key}: missing or not a list of the null runs' values"
    if len(vals) != runs:
        return f"{key}: {len(vals)} values, not one per run (runs = {runs})"
    for i, v in enumerate(vals):
        if not _is_number(v) or not math.isfinite(v):
            return f"{key}[{i}]: {v!r} is not a finite number"
    return None


def _expected_threshold(cal: dict, values: list) -> float:
    """The threshold the file's own method gives its null values."""
    from bench.gap import log_null, null

    method = str(cal.get("method", "")).lower()
    if "frechet" in method:
        return log_null.frechet_threshold(values, float(cal["false_alarm_target_each"]))
    if "predictive" in method:  # a calibration made for a log, kept as its vehicle's
        return log_null.tail_threshold(values, float(cal["false_alarm_target_each"]))[0]
    return null.quantile_threshold(np.asarray(values, float), float(cal["false_alarm_target_each"]))


def problem(cal) -> str | None:
    """The first thing that makes ``cal`` no usable calibration, as
    "field: what is wrong"; None when its shape and thresholds hold (the
    fingerprint against the log is checked by log_null.check_supplied)."""
    from bench.gap import log_null

    if not isinstance(cal, dict):
        return "expected a JSON object (a null calibration)"
    thr = cal.get("thresholds")
    thr = thr if isinstance(thr, dict) else {}
    for k in log_null.STATISTICS:
        t = thr.get(k)
        if t is None:
            return (
                f"thresholds.{k} missing: " + ("an empty object" if not cal else "this") + " is not a null calibration"
            )
        if not _is_number(t) or not math.isfinite(t) or t <= 0.0:
            return f"thresholds.{k}: {t!r} is not a finite positive number"
    runs = cal.get("runs")
    if isinstance(runs, bool) or not isinstance(runs, int) or not 1 <= runs <= 10**6:
        return f"runs: {runs!r} is not a whole number of runs (1 to 1000000)"
    fa = cal.get("false_alarm_target_each")
    if not _is_number(fa) or not 0.0 < fa < 1.0:
        return f"false_alarm_target_each: {fa!r} is not a rate between 0 and 1"
    for k in log_null.STATISTICS:
        why = _finite_list(cal, f"null_{k}", runs)
        if why:
            return why
    if "for_log" in cal and not isinstance(cal["for_log"], bool):
        return f"for_log: {cal['for_log']!r} is not true or false"
    if cal.get("for_log"):
        if cal.get("version") != log_null.VERSION:
            return (
                f"version: {cal.get('version')!r}, made by another version of the calibration "
                f"(this code's: {log_null.VERSION})"
            )
        if not isinstance(cal.get("fingerprint"), str) or not FINGERPRINT.fullmatch(cal["fingerprint"]):
            return "fingerprint: missing or not a SHA-256 (64 hex digits)"
        seed = cal.get("seed")
        if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63:
            return f"seed: {seed!r} is not a non-negative whole number"
        return log_null.unusable(cal, runs=runs)  # names the field: thresholds.K or null_K
    if "version" in cal and cal["version"] != log_null.VERSION:
        return (
            f"version: {cal['version']!r}, made by another version of the calibration (this code's: {log_null.VERSION})"
        )
    for k in log_null.STATISTICS:
        expect = _expected_threshold(cal, cal[f"null_{k}"])
        if not np.isclose(thr[k], expect, rtol=1e-9, atol=0.0):
            return f"thresholds.{k}: {thr[k]:.6g} is not the {expect:.6g} its null values give"
    return None
