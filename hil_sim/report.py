"""Report folder of a HIL run: the flight log (docs/FLIGHT_LOG.md) and plots."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.report import matplotlib_agg
from bench.sim.flight_log import FlightLogError, runs_to_flight_log, write_flight_log
from bench.sim.scenario_docking import DockingRun, errors_from_first_update


def plot_run(run: DockingRun, path: Path, title: str):
    plt = matplotlib_agg()
    e = errors_from_first_update(run)
    fig, ax = plt.subplots(4, 1, figsize=(9, 11), sharex=True)
    labels = "xyz"
    for block, a, unit in (("pos", ax[0], "m"), ("vel", ax[1], "m/s")):
        off = 0 if block == "pos" else 3
        for i in range(3):
            (line,) = a.plot(e.t, e.block(block)[:, i], label=f"{labels[i]}")
            a.plot(e.t, 3 * e.sigma[:, off + i], "--", color=line.get_color(), lw=0.7)
            a.plot(e.t, -3 * e.sigma[:, off + i], "--", color=line.get_color(), lw=0.7)
        a.set_ylabel(f"{block} error [{unit}]")
        a.legend(loc="upper right", ncol=3)
        a.grid(alpha=0.3)
    ax[2].semilogy(run.t, [np.trace(P) for P in run.P])
    ax[2].set_ylabel("trace P")
    ax[2].grid(alpha=0.3)
    u = run.updates
    ax[3].plot(u.t_fused, u.nis, "o", ms=3)
    ax[3].axhline(22.46, color="r", lw=0.8, label="gate (chi2 6, p=0.999)")
    ax[3].axhline(6.0, color="k", lw=0.8, ls=":", label="expected (6)")
    ax[3].set_ylabel("NIS")
    ax[3].set_xlabel("t [s]")
    ax[3].legend(loc="upper right")
    ax[3].grid(alpha=0.3)
    fig.suptitle(title + "  (dashed: +/- 3 sigma from the flight covariance)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_latency(lat_ms: np.ndarray, path: Path):
    plt = matplotlib_agg()
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.hist(lat_ms, bins=80, log=True)
    for q, ls in ((50, "-"), (99, "--")):
        v = np.percentile(lat_ms, q)
        ax.axvline(v, color="k", ls=ls, label=f"p{q} = {v:.3f} ms")
    ax.set_xlabel("step latency (send to complete telemetry) [ms]")
    ax.set_ylabel("steps")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _received_only(log) -> dict:
    """Leaves out the rows of the pose, estimate and update streams that hold
    a value the link never brought back (NaN: an estimate lost, a pose not
    sent); returns {stream: rows left out}."""
    left_out = {}
    for name in ("pose", "estimate", "update"):
        data = log.streams.get(name)
        if not data:
            continue
        n = len(next(iter(data.values())))
        keep = np.ones(n, bool)
        for v in data.values():
            a = np.asarray(v)
            if np.issubdtype(a.dtype, np.floating):
                keep &= np.all(np.isfinite(a.reshape(n, -1)), axis=1)
        if not keep.all():
            log.streams[name] = {k: np.asarray(v)[keep] for k, v in data.items()}
            left_out[name] = int(n - keep.sum())
    return left_out


def write_hil_report(res: dict, summary: dict, out: Path) -> str | None:
    """Writes the flight log and plots into ``out``; returns why the flight
    log was not written (a link that lost too much for a valid log), or None."""
    cfg = {
        "scenario": summary["scenario"],
        "seed": summary["seed"],
        "faults": summary["faults"],
        "orbit_radius_m": 6378137.0 + 500e3,
        "dt_imu_s": 0.1,
        "source": "proxops hil",
    }
    log = runs_to_flight_log(res["runs"], cfg)
    left_out = _received_only(log)
    if left_out:
        log.config["rows_left_out_lost_on_link"] = left_out
    why = None
    try:
        write_flight_log(out / "flight_log.h5", log)
    except FlightLogError as exc:
        why = f"flight log not written: what the link brought back is no valid log ({str(exc)[:160]})"
    plot_run(res["runs"][0], out / "nav_errors.png", "Docking over the HIL link: navigation errors")
    if res["steps"]:
        plot_latency(res["step_latency_ms"], out / "step_latency.png")
    return why
