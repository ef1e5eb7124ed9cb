"""The gap map: where, in the nominal replay's whitened innovations, the model
and the log disagree.

Cells: stream (pose position, Hill axes; pose attitude, body axes) x axis x
regime (all, coasting, firing, slewing) x statistic:
  mean      z = mean(e) sqrt(n)                      (a bias)
  variance  z = (sum e^2 - n) / sqrt(2 n)            (too much scatter)
  lag       z = max_{l=1..5} |rho_l| sqrt(n), signed  (correlation in time)
  lowfreq   z = (sum of the lowest-eighth periodogram bins / n_low - 1) sqrt(n_low)
            (power at low frequency; the peak frequency is reported)
Under a consistent model every z is about N(0, 1); their significance is
read against the null calibration (bench/gap/null.py), which gives the
distribution of the largest |z| over the whole map on simulated-on-simulated
logs, so each cell's p-value is family-wise.
"""

from __future__ import annotations

import numpy as np

from bench.gap.load import LogData
from bench.gap.replay import ReplayResult
from bench.so3 import rotmats

STREAMS = (("pose position", 0, "xyz (Hill)"), ("pose attitude", 3, "xyz (body)"))
REGIMES = ("all", "coasting", "firing", "slewing")
STATS = ("mean", "variance", "lag", "lowfreq")
MIN_CELL = 8  # fewer updates than this: no statistic


def regimes(d: LogData, res: ReplayResult) -> dict:
    """Boolean masks over the updates: firing (a valve open in the second
    before the capture; without a valve stream, |accel| above the noise),
    slewing (rate relative to Hill above 0.01 rad/s), coasting (neither)."""
    win = max(1, int(round(1.0 / d.dt_s)))
    k = np.clip(d.pose_tick[res.index], 0, d.imu_t.size - 1)
    if d.valves is not None:
        on = d.firing.astype(float)
    else:
        sig = d.desc.accel_sigma_mps2 if d.desc is not None else 1.667e-3
        on = (np.linalg.norm(d.accel, axis=1) > 1.5 * sig).astype(float)
    c = np.concatenate([[0.0], np.cumsum(on)])
    lo = np.clip(k - win + 1, 0, None)
    firing = (c[k + 1] - c[lo]) > 0
    if d.ref_q is not None:
        w_h = np.einsum("nji,j->ni", rotmats(d.ref_q), np.array([0.0, 0.0, d.n_radps]))
        w_bh = np.linalg.norm(d.gyro - w_h, axis=1)
    else:
        w_bh = np.linalg.norm(d.gyro, axis=1)
    cw = np.concatenate([[0.0], np.cumsum(w_bh)])
    slewing = (cw[k + 1] - cw[lo]) / (k + 1 - lo) > 0.01
    return {"all": np.ones(k.size, bool), "coasting": ~firing & ~slewing, "firing": firing, "slewing": slewing}


def _lag_z(e: np.ndarray):
    n = e.size
    e = e - e.mean()
    den = float(e @ e) or 1.0
    best, lag = 0.0, 1
    for l in range(1, 6):
        if n - l < MIN_CELL:
            break
        rho = float(e[:-l] @ e[l:]) / den
        if abs(rho) > abs(best):
            best, lag = rho, l
    return best * np.sqrt(n), lag


def _lowfreq_z(e: np.ndarray, period_s: float):
    n = e.size
    p = np.abs(np.fft.rfft(e)) ** 2 / n
    f = np.fft.rfftfreq(n, period_s)
    p, f = p[1:], f[1:]  # the mean has its own cell
    if p.size < 8:
        return 0.0, float("nan")
    n_low = max(1, p.size // 8)
    z = (p[:n_low].mean() - 1.0) * np.sqrt(n_low)
    return float(z), float(f[int(np.argmax(p))])


def gap_map(d: LogData, res: ReplayResult, white: np.ndarray | None = None) -> list:
    """List of cells (dicts: stream, axis, regime, stat, n, z, extra)."""
    e_all = res.whitened() if white is None else white
    masks = regimes(d, res)
    period = float(np.median(np.diff(res.t))) if res.t.size > 1 else 1.0
    cells = []
    for stream, off, axes in STREAMS:
        for a in range(3):
            for regime in REGIMES:
                m = masks[regime]
                e = e_all[m, off + a]
                n = e.size
                if n < MIN_CELL:
                    continue
                base = {"stream": stream, "axis": "xyz"[a], "frame": axes.split()[1][1:-1], "regime": regime, "n": n}
                cells.append({**base, "stat": "mean", "z": float(e.mean() * np.sqrt(n)), "value": float(e.mean())})
                cells.append(
                    {**base, "stat": "variance", "z": float((e @ e - n) / np.sqrt(2 * n)), "value": float(e @ e / n)}
                )
                if regime == "all":
                    z, lag = _lag_z(e)
                    cells.append({**base, "stat": "lag", "z": float(z), "value": int(lag)})
                    z, fpk = _lowfreq_z(e, period)
                    cells.append({**base, "stat": "lowfreq", "z": z, "value": fpk})
    return cells


def map_statistic(cells: list) -> float:
    """The largest |z| over the map: the localisation's detection statistic."""
    return float(max((abs(c["z"]) for c in cells), default=0.0))


def summarise(cells: list, null_max_z: np.ndarray | None, top: int = 5) -> dict:
    """The most significant cells with family-wise p-values, and where the gap lies."""
    ranked = sorted(cells, key=lambda c: -abs(c["z"]))
    out = []
    for c in ranked[:top]:
        c = dict(c)
        if null_max_z is not None and len(null_max_z):
            k = int(np.sum(np.asarray(null_max_z) >= abs(c["z"])))
            c["p_familywise"] = float((1 + k) / (1 + len(null_max_z)))
            c["p_beyond_null"] = k == 0  # larger than every null run: p is an upper bound
        out.append(c)
    where = None
    if ranked:
        b = ranked[0]
        reg = {r: max((abs(c["z"]) for c in cells if c["regime"] == r), default=0.0) for r in REGIMES[1:]}
        where = {
            "stream": b["stream"],
            "axis": b["axis"],
            "frame": b["frame"],
            "stat": b["stat"],
            "regime_peak": max(reg, key=reg.get) if reg else "all",
            "regime_max_abs_z": reg,
        }
    return {"top_cells": out, "where": where}


DYN_STREAMS = (("imu accel vs valves", 0), ("gyro vs valve torques", 1))


def dyn_regimes(d: LogData, ch) -> dict:
    """Per dynamics row: firing (a valve open in that IMU interval), slewing
    (rate relative to Hill above 0.01 rad/s), coasting (neither)."""
    n = d.imu_t.size
    k = np.concatenate([np.arange(n), ch.gyro_rows])
    firing = d.firing[k]
    # Slewing from the gyro averaged over 1 s (a single sample's noise would
    # select the noisy rows and bias the regime cells).
    win = max(1, int(round(1.0 / d.dt_s)))
    ker = np.ones(win) / win
    w_avg = np.stack([np.convolve(d.gyro[:, i], ker, mode="same") for i in range(3)], axis=1)
    if d.ref_q is not None:
        w_h = np.einsum("nji,j->ni", rotmats(d.ref_q), np.array([0.0, 0.0, d.n_radps]))
        w_bh = np.linalg.norm(w_avg - w_h, axis=1)
    else:
        w_bh = np.linalg.norm(w_avg, axis=1)
    slewing = w_bh[k] > 0.01
    return {"all": np.ones(k.size, bool), "coasting": ~firing & ~slewing, "firing": firing, "slewing": slewing}


def dyn_cells(d: LogData, ch, rows: np.ndarray | None = None) -> list:
    """Gap-map cells of the dynamics channel (rows: its whitened (R, 3) rows)."""
    if ch is None:
        return []
    e_all = ch.e0 if rows is None else rows
    masks = dyn_regimes(d, ch)
    gyro = ch.kind == 1
    # Regime cells of the gyro stream use the raw differences: a whitened row
    # carries every earlier row's error (the inverse Cholesky factor is dense),
    # so a torque error made while firing would show in the coasting rows after.
    raw_g = ch.unwhiten_gyro(e_all[gyro])
    adj = ch.adjacent_gyro_rows()
    cells = []
    for stream, kind in DYN_STREAMS:
        sel = ch.kind == kind
        for a in range(3):
            for regime in REGIMES:
                m = sel & masks[regime]
                n = int(m.sum())
                if n < MIN_CELL:
                    continue
                base = {"stream": stream, "axis": "xyz"[a], "frame": "body", "regime": regime, "n": n}
                if kind == 1 and regime != "all":
                    mg = m[gyro]
                    x = raw_g[mg, a]
                    # Differences of white noise: variance 2, lag-1 covariance -1.
                    p = int(np.sum(mg[:-1] & mg[1:] & adj[:-1]))
                    cells.append(
                        {**base, "stat": "mean", "z": float(x.sum() / np.sqrt(2 * n - 2 * p)), "value": float(x.mean())}
                    )
                    cells.append(
                        {
                            **base,
                            "stat": "variance",
                            "z": float((x @ x - 2 * n) / np.sqrt(8 * n + 4 * p)),
                            "value": float(x @ x / (2 * n)),
                        }
                    )
                    continue
                e = e_all[m, a]
                cells.append({**base, "stat": "mean", "z": float(e.mean() * np.sqrt(n)), "value": float(e.mean())})
                cells.append(
                    {**base, "stat": "variance", "z": float((e @ e - n) / np.sqrt(2 * n)), "value": float(e @ e / n)}
                )
                if regime == "all":
                    z, lag = _lag_z(e)
                    cells.append({**base, "stat": "lag", "z": float(z), "value": int(lag)})
                    z, fpk = _lowfreq_z(e, d.dt_s)
                    cells.append({**base, "stat": "lowfreq", "z": z, "value": fpk})
    return cells


def signature_regimes(
    d: LogData,
    ch,
    nominal_white: np.ndarray,
    after_white: np.ndarray,
    res: ReplayResult | None,
    after_dyn: np.ndarray | None,
) -> dict:
    """Where a fitted effect acts: its signature's energy per row (the change
    it makes to the residuals, gyro rows as raw differences) in each regime.
    Returns {regime: mean energy per row} and the regime where it peaks."""
    energy = {r: [0.0, 0] for r in REGIMES[1:]}
    if res is not None and res.index.size:
        dn = np.nan_to_num(after_white[res.index] - nominal_white[res.index])
        m = regimes(d, res)
        en = np.sum(dn**2, axis=1)
        for r in REGIMES[1:]:
            energy[r][0] += float(en[m[r]].sum())
            energy[r][1] += int(m[r].sum())
    if ch is not None and after_dyn is not None:
        delta = after_dyn - ch.e0
        g = ch.kind == 1
        delta[g] = ch.unwhiten_gyro(delta[g]) / np.sqrt(2.0)
        en = np.sum(delta**2, axis=1)
        m = dyn_regimes(d, ch)
        for r in REGIMES[1:]:
            energy[r][0] += float(en[m[r]].sum())
            energy[r][1] += int(m[r].sum())
    per_row = {r: (e / n if n else 0.0) for r, (e, n) in energy.items()}
    peak = max(per_row, key=per_row.get) if any(per_row.values()) else None
    return {"energy_per_row": per_row, "peak": peak}
