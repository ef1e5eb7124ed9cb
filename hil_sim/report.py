"""Report folder of a HIL run: the flight log (docs/FLIGHT_LOG.md) and plots."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.report import matplotlib_agg
from bench.sim.flight_log import FlightLogError, write_flight_log
from bench.sim.reality import runs_to_log
from bench.sim.scenario_docking import DockingRun, errors_from_first_update

# Per state block: the error's attribute, its columns of P, display unit and scale.
BLOCKS = (("pos", 0, "m", 1.0), ("vel", 3, "mm/s", 1e3), ("att", 6, "mrad", 1e3))
NIS_GATE = 22.46  # chi-square, 6 dof, p = 0.999: the flight filter's gate


def _run_label(run: DockingRun, k: int) -> str:
    s = run.summary
    how = "docked" if s.docked else "cut short" if s.cut_by_duration else "not docked"
    return f"run {k + 1} ({how} at {s.t_end_s:.0f} s)"


def _error_panels(fig, grid, runs) -> list:
    """A 3 x 3 grid: position, velocity and attitude error per axis, each run
    in its colour with its own +/- 3 sigma from the flight covariance."""
    axes = []
    for row, (block, col0, unit, scale) in enumerate(BLOCKS):
        for j, axis in enumerate("xyz"):
            a = fig.add_subplot(grid[row, j], sharex=axes[0] if axes else None)
            for k, run in enumerate(runs):
                e = errors_from_first_update(run)
                color = f"C{k % 10}"
                a.plot(e.t, scale * e.block(block)[:, j], color=color, lw=0.9)
                sig = 3 * scale * e.sigma[:, col0 + j]
                a.plot(e.t, sig, "--", color=color, lw=0.6)
                a.plot(e.t, -sig, "--", color=color, lw=0.6)
            a.set_title(f"{block} {axis}", fontsize=9)
            if j == 0:
                a.set_ylabel(f"{block} error [{unit}]")
            a.grid(alpha=0.3)
            axes.append(a)
    return axes


def nav_errors_figure(runs, title: str):
    """Navigation errors of every run with their 3-sigma bounds, and the NIS
    of every pose update against its gate; the legend below the panels."""
    plt = matplotlib_agg()
    fig = plt.figure(figsize=(11, 11))
    grid = fig.add_gridspec(4, 3, height_ratios=(1, 1, 1, 0.9))
    axes = _error_panels(fig, grid, runs)
    nis = fig.add_subplot(grid[3, :], sharex=axes[0])
    for k, run in enumerate(runs):
        u = run.updates
        nis.plot(u.t_fused, u.nis, "o", ms=3, color=f"C{k % 10}", label=_run_label(run, k))
    nis.axhline(NIS_GATE, color="r", lw=0.8, label="gate (chi-square 6 dof, p = 0.999)")
    nis.axhline(6.0, color="k", lw=0.8, ls=":", label="expected (6)")
    nis.set_ylabel("NIS [-]")
    nis.set_xlabel("time since the run's start [s]")
    nis.grid(alpha=0.3)
    nis.legend(loc="upper center", bbox_to_anchor=(0.5, -0.28), ncol=min(4, len(runs) + 2), fontsize=8)
    fig.suptitle(
        f"{title}: {len(runs)} run(s), from each run's first pose update (solid: error; dashed: +/- 3 sigma of the "
        "flight covariance)",
        fontsize=10,
    )
    fig.tight_layout()
    return fig


def plot_runs(runs, path: Path, title: str):
    plt = matplotlib_agg()
    fig = nav_errors_figure(runs, title)
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
    # With the valve commands the plant flew (every step's configuration),
    # so a diagnosis of this log examines the dynamics channel.
    log = runs_to_log(res["runs"], cfg)
    left_out = _received_only(log)
    if left_out:
        log.config["rows_left_out_lost_on_link"] = left_out
    why = None
    try:
        write_flight_log(out / "flight_log.h5", log)
    except FlightLogError as exc:
        why = f"flight log not written: what the link brought back is no valid log ({str(exc)[:160]})"
    plot_runs(res["runs"], out / "nav_errors.png", "Docking over the HIL link")
    if res["steps"]:
        plot_latency(res["step_latency_ms"], out / "step_latency.png")
    return why
