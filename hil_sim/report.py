"""Report folder of a HIL run: the flight log (docs/FLIGHT_LOG.md) and plots."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.report import matplotlib_agg
from bench.sim.flight_log import runs_to_flight_log, write_flight_log
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


def write_hil_report(res: dict, summary: dict, out: Path):
    cfg = {
        "scenario": summary["scenario"],
        "seed": summary["seed"],
        "faults": summary["faults"],
        "orbit_radius_m": 6378137.0 + 500e3,
        "dt_imu_s": 0.1,
        "source": "proxops hil",
    }
    write_flight_log(out / "flight_log.h5", runs_to_flight_log(res["runs"], cfg))
    plot_run(res["runs"][0], out / "nav_errors.png", "Docking over the HIL link: navigation errors")
    if res["steps"]:
        plot_latency(res["step_latency_ms"], out / "step_latency.png")
