"""Seeded Monte Carlo of docking runs and the navigation metrics
(docs/perf/nav_campaign.md).

Run i of a campaign with seed S uses the scenario seed S * 1000 + i; each
run is a task on a Dask cluster (bench/runner), kept in a results store
as it finishes.

Metrics, every sample from the run's first pose update on:
  * max_pos_err_m / max_vel_err_mps: per run, the largest absolute per-axis
    error (Hill axes) over all 10 Hz samples; then the median and the 95th
    percentile (numpy's linear interpolation) over the runs.
  * nees_mean: mean of e^T P^-1 e (9 dof) over every 10 Hz sample of every run;
    nis_mean: mean NIS (6 dof) over every fused pose update of every run.
    Each is the average over the N runs (of each run's time average), tested
    against the N-run band of Bar-Shalom, Li and Kirubarajan (sec. 5.4.2):
    N times the average of N independent chi2(dof) is chi2(N dof), so the
    band is chi2.ppf([0.025, 0.975], dof N) / N. One epoch's N-run average
    has exactly that distribution; a time average of it spreads no wider.
    The exact per-epoch test (nees_ensemble, nis_ensemble) is reported too,
    and so is the band that would hold if every sample were independent
    (nees_band_per_sample: far too narrow for 10 Hz NEES samples, which are
    correlated over seconds; honest for NIS, whose samples are white), with
    the 1 Hz posterior NEES, the NEES every 10 s (nearly independent
    samples), and the standard error of nees_mean from the per-run means.
  * gated_count: pose updates the filter rejected by its chi-square gate.
  * vision_status_counts (pose_source "images" only): the flight vision
    pipeline's status for every rendered frame of every run, by reason; a
    frame that is not Ok delivers no pose.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2

from bench.sim.scenario_docking import (
    NAV_DOF,
    POSE_DOF,
    DockingRun,
    DockingSummary,
    ScenarioConfig,
    errors_from_first_update,
    run_docking,
)

# Every THIN_EVERY-th post-update NEES (10 s apart) is nearly independent of
# the previous one, so the chi-square band of the mean holds for the thinned set.
THIN_EVERY = 10


def chi2_mean_band(dof: int, count: int, p: float = 0.95) -> list[float]:
    """Two-sided band of the mean of `count` independent chi2(dof) samples."""
    a = (1.0 - p) / 2.0
    return [float(chi2.ppf(a, dof * count) / count), float(chi2.ppf(1.0 - a, dof * count) / count)]


def run_seed(base_seed: int, i: int) -> int:
    return int(base_seed) * 1000 + int(i)


@dataclass
class RunMetrics:
    seed: int
    docked: bool
    t_end_s: float
    max_pos_err_m: float
    max_vel_err_mps: float
    max_att_err_rad: float
    nees: np.ndarray  # 10 Hz samples from the first update on
    nees_step: np.ndarray  # 10 Hz step index (t / 0.1) of each nees sample
    nees_post_1hz: np.ndarray  # just after each fused update
    nis: np.ndarray  # fused updates
    nis_epoch: np.ndarray  # capture time of each fused update, rounded to the 1 Hz epoch [s]
    nis_pos: np.ndarray  # position block of the innovation (3 dof)
    nis_att: np.ndarray  # attitude block (3 dof)
    nees_blocks: np.ndarray  # (n, 3): pos, vel, att blocks, each 3 dof
    statuses: dict = field(default_factory=dict)
    summary: DockingSummary | None = None

    @classmethod
    def from_record(cls, d: dict) -> RunMetrics:
        """Metrics as a results store gives them back (dataclasses as dicts)."""
        return cls(**{**d, "summary": DockingSummary(**d["summary"])})


def run_metrics(run: DockingRun) -> RunMetrics:
    e = errors_from_first_update(run)
    u = run.updates
    fused = u.fused.astype(bool) if len(u.fused) else np.zeros(0, bool)
    nis_pos, nis_att = [], []
    for nu, S in zip(u.innovation[fused], u.S[fused]):
        nis_pos.append(nu[:3] @ np.linalg.solve(S[:3, :3], nu[:3]))
        nis_att.append(nu[3:] @ np.linalg.solve(S[3:, 3:], nu[3:]))
    # Posterior NEES at the step at which each fused update was applied.
    idx = np.searchsorted(run.t, u.t_fused[fused] - 1e-9)
    err = np.hstack([e.pos, e.vel, e.att])
    sig2 = e.sigma**2
    blocks = np.stack(
        [np.sum(err[:, 3 * b : 3 * b + 3] ** 2 / sig2[:, 3 * b : 3 * b + 3], axis=1) for b in range(3)], 1
    )
    statuses = {}
    for s in list(run.predict_status) + list(u.status):
        statuses[str(s)] = statuses.get(str(s), 0) + 1  # plain str: numpy strings print as np.str_('ok')
    sm = run.summary
    return RunMetrics(
        seed=sm.seed,
        docked=sm.docked,
        t_end_s=sm.t_end_s,
        max_pos_err_m=float(np.max(np.abs(e.pos))),
        max_vel_err_mps=float(np.max(np.abs(e.vel))),
        max_att_err_rad=float(np.max(np.abs(e.att))),
        nees=e.nees,
        nees_step=np.rint(e.t / 0.1).astype(int),
        nees_post_1hz=run.nees[idx],
        nis=u.nis[fused],
        nis_epoch=np.rint(np.asarray(u.t_capture)[fused]).astype(int),
        nis_pos=np.array(nis_pos),
        nis_att=np.array(nis_att),
        nees_blocks=blocks,
        statuses=statuses,
        summary=sm,
    )


def _dist(x) -> dict:
    x = np.asarray(x, float)
    return {"per_run": x.tolist(), "median": float(np.median(x)), "p95": float(np.percentile(x, 95))}


def _mean_band(samples, dof) -> tuple[float, list[float], int]:
    x = np.concatenate([np.ravel(s) for s in samples]) if samples else np.zeros(0)
    return float(np.mean(x)) if x.size else float("nan"), chi2_mean_band(dof, max(x.size, 1)), int(x.size)


def ensemble_consistency(values, keys, dof: int, min_runs: int, p: float = 0.95) -> dict:
    """The N-run Monte Carlo average at each epoch (Bar-Shalom, Li and
    Kirubarajan, sec. 5.4.2): eps_k = mean over the runs active at epoch k of
    their NEES (or NIS) at k, tested against chi2.ppf([a, 1-a], dof n_k) / n_k.
    Runs are independent, so the band is exact at every epoch; a consistent
    filter keeps a fraction p of epochs inside it. Epochs with fewer than
    min_runs runs (the tail, after most runs have docked) are left out."""
    sums: dict[int, list[float]] = {}
    for v, k in zip(values, keys):
        for vi, ki in zip(np.ravel(v), np.ravel(k)):
            sums.setdefault(int(ki), []).append(float(vi))
    epochs = sorted(k for k, xs in sums.items() if len(xs) >= min_runs)
    if not epochs:
        return {"epochs": 0, "in_band_fraction": float("nan"), "expected_fraction": p}
    means = np.array([np.mean(sums[k]) for k in epochs])
    counts = np.array([len(sums[k]) for k in epochs])
    a = (1.0 - p) / 2.0
    lo = chi2.ppf(a, dof * counts) / counts
    hi = chi2.ppf(1.0 - a, dof * counts) / counts
    inside = (means >= lo) & (means <= hi)
    return {
        "epochs": len(epochs),
        "runs_per_epoch_min": int(counts.min()),
        "runs_per_epoch_max": int(counts.max()),
        "band_at_max_runs": [float(lo[np.argmax(counts)]), float(hi[np.argmax(counts)])],
        "in_band_fraction": float(inside.mean()),
        "below_band": int(np.sum(means < lo)),
        "above_band": int(np.sum(means > hi)),
        "expected_fraction": p,
        "mean_of_epoch_means": float(means.mean()),
        "epoch_keys": [int(k) for k in epochs],
        "epoch_means": means.tolist(),
        "band_lo": lo.tolist(),
        "band_hi": hi.tolist(),
    }


def summarise(metrics: list[RunMetrics], cfg: ScenarioConfig, seed: int) -> dict:
    pos = _dist([m.max_pos_err_m for m in metrics])
    vel = _dist([m.max_vel_err_mps for m in metrics])
    consistency = _consistency(metrics)
    statuses = {}
    for m in metrics:
        for k, v in m.statuses.items():
            statuses[k] = statuses.get(k, 0) + v
    return {
        "runs": len(metrics),
        "seed": int(seed),
        "run_seeds": [m.seed for m in metrics],
        "dynamics": cfg.dynamics,
        "init": cfg.init,
        "pose_R_from": cfg.pose_R_from,
        "accel_source": cfg.accel_source,
        "pose_source": cfg.pose_source,
        **(_vision(metrics) if cfg.pose_source == "images" else {}),
        "blr_steps": int(sum(m.summary.blr_steps for m in metrics)),
        "firing_steps": int(sum(m.summary.firing_steps for m in metrics)),
        "profile": {k: (list(v) if isinstance(v, tuple) else v) for k, v in cfg.profile.__dict__.items()},
        "max_pos_err_m": pos,
        "max_vel_err_mps": vel,
        "max_att_err_rad": _dist([m.max_att_err_rad for m in metrics]),
        **consistency,
        "gated_count": int(sum(m.statuses.get("gated", 0) for m in metrics)),
        "status_counts": statuses,
        "docked": int(sum(m.docked for m in metrics)),
        "t_end_s": [m.t_end_s for m in metrics],
        "checks": _checks(pos, vel, consistency),
    }


def _vision(metrics: list[RunMetrics]) -> dict:
    """The vision pipeline's frames by status, over the runs (pose_source "images")."""
    counts = {}
    for m in metrics:
        for k, v in m.summary.vision_status_counts.items():
            counts[k] = counts.get(k, 0) + int(v)
    return {
        "vision_status_counts": counts,
        "vision_frames": int(sum(counts.values())),
        "fused_pose_count": int(sum(m.nis.size for m in metrics)),
        "runs_started_late": int(sum((m.summary.t_nav_init_s or 0.0) > 0.0 for m in metrics)),
    }


def _consistency(metrics: list[RunMetrics]) -> dict:
    """NEES and NIS over the runs against their bands (the module docstring)."""
    nees_mean, nees_band_sample, nees_count = _mean_band([m.nees for m in metrics], NAV_DOF)
    nis_mean, nis_band_sample, nis_count = _mean_band([m.nis for m in metrics], POSE_DOF)
    post_mean, post_band, post_count = _mean_band([m.nees_post_1hz for m in metrics], NAV_DOF)
    thin_mean, thin_band, thin_count = _mean_band([m.nees_post_1hz[::THIN_EVERY] for m in metrics], NAV_DOF)
    run_means = np.array([np.mean(m.nees) for m in metrics])
    # Per-epoch ensemble averages over the runs; 1 Hz epochs for NEES too (the
    # 10 Hz samples between two poses add no independent information).
    min_runs = max(2, len(metrics) // 2)
    nees_1hz = [m.nees[m.nees_step % 10 == 0] for m in metrics]
    nees_1hz_k = [m.nees_step[m.nees_step % 10 == 0] for m in metrics]
    blocks = np.vstack([m.nees_blocks for m in metrics])
    return {
        "nees_mean": nees_mean,
        "nees_band": chi2_mean_band(NAV_DOF, len(metrics)),
        "nees_band_kind": "N-run average: chi2.ppf([0.025, 0.975], 9 N) / N",
        "nees_band_per_sample": nees_band_sample,
        "nees_count": nees_count,
        "nis_mean": nis_mean,
        "nis_band": chi2_mean_band(POSE_DOF, len(metrics)),
        "nis_band_kind": "N-run average: chi2.ppf([0.025, 0.975], 6 N) / N",
        "nis_band_per_sample": nis_band_sample,
        "nis_count": nis_count,
        "nees_post_update_mean": post_mean,
        "nees_post_update_band": post_band,
        "nees_thinned_mean": thin_mean,
        "nees_thinned_band": thin_band,
        "nees_thinned_count": thin_count,
        "nees_ensemble": ensemble_consistency(nees_1hz, nees_1hz_k, NAV_DOF, min_runs),
        "nis_ensemble": ensemble_consistency(
            [m.nis for m in metrics], [m.nis_epoch for m in metrics], POSE_DOF, min_runs
        ),
        "nees_run_means": run_means.tolist(),
        "nees_mean_std_error": float(run_means.std(ddof=1) / np.sqrt(len(run_means))) if len(run_means) > 1 else None,
        "nees_block_means": {
            "pos": float(blocks[:, 0].mean()),
            "vel": float(blocks[:, 1].mean()),
            "att": float(blocks[:, 2].mean()),
            "dof_each": 3,
        },
        "nis_block_means": {
            "pos": float(np.mean(np.concatenate([m.nis_pos for m in metrics]))),
            "att": float(np.mean(np.concatenate([m.nis_att for m in metrics]))),
            "dof_each": 3,
        },
    }


def _checks(pos: dict, vel: dict, c: dict) -> dict:
    """The campaign's pass criteria."""

    def inside(band, x):
        return band[0] <= x <= band[1]

    return {
        "pos_p95_le_0.10": pos["p95"] <= 0.10,
        "vel_p95_le_0.03": vel["p95"] <= 0.03,
        "pos_median_le_0.05": pos["median"] <= 0.05,
        "vel_median_le_0.015": vel["median"] <= 0.015,
        "nees_in_band": inside(c["nees_band"], c["nees_mean"]),
        "nis_in_band": inside(c["nis_band"], c["nis_mean"]),
        "nees_in_per_sample_band": inside(c["nees_band_per_sample"], c["nees_mean"]),
        "nis_in_per_sample_band": inside(c["nis_band_per_sample"], c["nis_mean"]),
        "nees_ensemble_in_band_ge_0.95": c["nees_ensemble"]["in_band_fraction"] >= 0.95,
        "nis_ensemble_in_band_ge_0.95": c["nis_ensemble"]["in_band_fraction"] >= 0.95,
    }


def _run_one(item: dict, cfg: ScenarioConfig) -> dict:
    """One docking run (a campaign task): its metrics, and the raw run when kept for plots."""
    run = run_docking(item["seed"], cfg)
    return {"metrics": run_metrics(run), "run": run if item["keep_run"] else None}


def run_campaign(
    n_runs: int,
    seed: int,
    cfg: ScenarioConfig | None = None,
    progress: bool = False,
    keep_runs: int = 0,
    campaign=None,
    workers: int | None = None,
):
    """Returns (summary dict, list of the first ``keep_runs`` raw runs). Each
    run is a task of ``campaign`` (bench/runner/runner.py; default a local
    Dask cluster of ``workers``, nothing kept)."""
    from bench.runner.runner import Campaign, all_failed, failures, missing, results

    cfg = cfg or ScenarioConfig()
    campaign = campaign if campaign is not None else Campaign(workers=workers, progress=progress)
    items = [{"seed": run_seed(seed, i), "keep_run": i < keep_runs} for i in range(n_runs)]
    recs = campaign.map("run", _run_one, items, shared=cfg, label="nav")
    all_failed(recs)
    done = [r for r in results(recs) if r is not None]
    if not done:
        raise ValueError("no finished runs to summarise")
    summary = summarise([RunMetrics.from_record(r["metrics"]) for r in done], cfg, seed)
    if len(done) < n_runs:
        summary["runs_requested"] = n_runs
        summary["failed_runs"] = failures(recs)
        summary["missing_runs"] = missing(recs)
    if campaign.store.path is not None:
        summary["store"] = str(campaign.store.path)
    kept = [DockingRun.from_record(r["run"]) for r in results(recs)[:keep_runs] if r is not None]
    return summary, kept
