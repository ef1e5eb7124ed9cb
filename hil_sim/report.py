"""Report folder of a HIL run: the flight log (docs/FLIGHT_LOG.md) and plots."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.flight_log import FlightLog, STATUS_CODES, write_flight_log
from bench.report import matplotlib_agg
from bench.scenario_docking import errors_from_first_update


def runs_to_flight_log(runs, config: dict) -> FlightLog:
    """One flight log over chained runs (time tags run on from run to run)."""
    imu, pose, est, upd, truth = ({} for _ in range(5))
    offset = 0.0
    parts = {k: [] for k in ("imu_t", "acc", "gyr", "p_tc", "p_td", "p_r", "p_q", "p_rs", "p_as",
                              "e_t", "e_r", "e_v", "e_q", "e_p", "u_t", "u_st", "u_f", "u_in", "u_nis", "u_ll",
                              "t_t", "t_r", "t_v", "t_q", "t_w")}
    for run in runs:
        t = run["t"] + offset
        parts["imu_t"].append(run["imu_t"] + offset)
        parts["acc"].append(run["imu_accel"])
        parts["gyr"].append(run["imu_gyro"])
        u = run["updates"]
        parts["p_tc"].append(u["t_capture"] + offset)
        parts["p_td"].append(u["t_fused"] + offset)
        parts["p_r"].append(u["r_meas"])
        parts["p_q"].append(u["q_meas"])
        parts["p_rs"].append(u["r_sigma"])
        parts["p_as"].append(u["att_sigma"])
        parts["u_t"].append(u["t_fused"] + offset)
        parts["u_st"].append(np.array([STATUS_CODES[s] for s in u["status"]], dtype=int))
        parts["u_f"].append(np.asarray(u["fused"], dtype=int))
        parts["u_in"].append(np.asarray(u["innovation"]).reshape(-1, 6))
        parts["u_nis"].append(u["nis"])
        parts["u_ll"].append(u["loglik"])
        parts["e_t"].append(t)
        parts["e_r"].append(run["est"][:, 0:3])
        parts["e_v"].append(run["est"][:, 3:6])
        parts["e_q"].append(run["est"][:, 6:10])
        parts["e_p"].append(np.array([np.diag(P) for P in run["P"]]))
        parts["t_t"].append(t)
        parts["t_r"].append(run["r_true"])
        parts["t_v"].append(run["v_true"])
        parts["t_q"].append(run["q_true"])
        parts["t_w"].append(run["w_true"])
        offset = t[-1] + 0.1
    c = {k: np.concatenate(v) if v else np.zeros(0) for k, v in parts.items()}
    imu = {"t_s": c["imu_t"], "accel_b_mps2": c["acc"], "omega_bi_b_rps": c["gyr"]}
    pose = {"t_capture_s": c["p_tc"], "t_delivered_s": c["p_td"], "r_hill_m": c["p_r"], "q_hb": c["p_q"],
            "r_sigma_m": c["p_rs"], "att_sigma_rad": c["p_as"]}
    est = {"t_s": c["e_t"], "r_hill_m": c["e_r"], "v_hill_mps": c["e_v"], "q_hb": c["e_q"], "p_diag": c["e_p"]}
    upd = {"t_s": c["u_t"], "status": c["u_st"], "fused": c["u_f"], "innovation": c["u_in"],
           "nis": c["u_nis"], "log_likelihood": c["u_ll"]}
    truth = {"t_s": c["t_t"], "r_hill_m": c["t_r"], "v_hill_mps": c["t_v"], "q_hb": c["t_q"],
             "omega_bi_b_rps": c["t_w"]}
    # The first record of each run is its initial state (same time as the
    # previous run's end + offset): keep the time strictly increasing.
    return FlightLog(streams={"imu": imu, "pose": pose, "estimate": est, "update": upd, "truth": truth},
                     config=config)


def plot_run(run: dict, path: Path, title: str):
    plt = matplotlib_agg()
    e = errors_from_first_update(run)
    fig, ax = plt.subplots(4, 1, figsize=(9, 11), sharex=True)
    labels = "xyz"
    for block, a, unit in (("pos", ax[0], "m"), ("vel", ax[1], "m/s")):
        off = 0 if block == "pos" else 3
        for i in range(3):
            line, = a.plot(e["t"], e[block][:, i], label=f"{labels[i]}")
            a.plot(e["t"], 3 * e["sigma"][:, off + i], "--", color=line.get_color(), lw=0.7)
            a.plot(e["t"], -3 * e["sigma"][:, off + i], "--", color=line.get_color(), lw=0.7)
        a.set_ylabel(f"{block} error [{unit}]")
        a.legend(loc="upper right", ncol=3)
        a.grid(alpha=0.3)
    ax[2].semilogy(run["t"], [np.trace(P) for P in run["P"]])
    ax[2].set_ylabel("trace P")
    ax[2].grid(alpha=0.3)
    u = run["updates"]
    ax[3].plot(u["t_fused"], u["nis"], "o", ms=3)
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
    cfg = {"scenario": summary["scenario"], "seed": summary["seed"], "faults": summary["faults"],
           "orbit_radius_m": 6378137.0 + 500e3, "dt_imu_s": 0.1, "source": "proxops hil"}
    write_flight_log(out / "flight_log.h5", runs_to_flight_log(res["runs"], cfg))
    plot_run(res["runs"][0], out / "nav_errors.png", "Docking over the HIL link: navigation errors")
    if res["steps"]:
        plot_latency(res["step_latency_ms"], out / "step_latency.png")

