"""Image-pipeline accuracy campaign for the LED pose (docs/VISION.md).

Random inspector poses with the host's pattern in view (camera to pattern
0.3 to 5 m), each rendered under every condition (nominal, blur, clutter,
sun) and passed through the flight vision pipeline (fsw_bindings
LedPoseEstimator). Per case: status, pose error against truth, NEES against
the covariance the pipeline reports. Per condition: failure counts by
reason, error statistics, the mean NEES against its 95% band and the
fraction of cases inside the per-case chi2(6) 95% bound.

Distortion experiment: the same kind of poses rendered through a lens with
radial distortion k1 while the pipeline assumes none. The predicted pose
error is the least-squares response of the pipeline to the distortion's
pixel displacement, dx = (J^T J)^-1 J^T (px_distorted - px_pinhole), with J
the pipeline's own reprojection Jacobian at the truth.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from bench.sim import camera as cm
from bench.so3 import boxminus

STATUSES = [
    "Ok",
    "TooFewLeds",
    "AmbiguousIdentity",
    "TargetBehindCamera",
    "DegenerateGeometry",
    "SolverFailed",
    "BadInput",
]
GROSS_NEES = float(chi2.ppf(0.9999, 6))  # beyond this an "Ok" pose is a gross error
RANGE_BINS_M = (0.3, 1.0, 2.0, 3.0, 4.0, 5.0)  # camera to pattern, for the per-range summary


def pose_error(r_meas, q_meas, r_true, q_true) -> np.ndarray:
    """[position (Hill) m, body-frame attitude rad]: estimate minus truth, the filter's convention."""
    return np.concatenate([np.asarray(r_meas) - r_true, boxminus(np.asarray(q_meas), q_true)])


def run_case(est, r, q, qh, scene: cm.Scene, rng, cam: cm.Camera, t_s: float = 0.0) -> dict:
    img = cm.render(r, q, qh, scene, rng, cam)
    m = est.estimate(img, t_s, qh)
    out = {
        "status": m.status,
        "range_m": float(np.linalg.norm(cm.led_pixels(r, q, qh, cam)[2][:4].mean(0))),
        "n_blobs": int(m.n_blobs),
        "identifier_split": bool(m.identifier_split),
    }
    if m.ok:
        e = pose_error(m.r_hill_m, m.q_hb, r, q)
        R = m.R
        out.update(
            pos_err_m=float(np.linalg.norm(e[:3])),
            att_err_deg=float(np.degrees(np.linalg.norm(e[3:]))),
            nees=float(e @ np.linalg.solve(R, e)),
            sigma_pos_m=float(np.sqrt(np.trace(R[:3, :3]))),
            sigma_att_deg=float(np.degrees(np.sqrt(np.trace(R[3:, 3:])))),
            reproj_rms_px=float(m.reproj_rms_px),
        )
    return out


def summarise(cases: list[dict]) -> dict:
    n = len(cases)
    ok = [c for c in cases if c["status"] == "Ok"]
    fails = {s: sum(c["status"] == s for c in cases) for s in STATUSES if s != "Ok"}
    s = {
        "cases": n,
        "ok": len(ok),
        "failure_rate": (n - len(ok)) / n if n else 0.0,
        "failures_by_reason": {k: v for k, v in fails.items() if v},
    }
    if ok:
        nees = np.array([c["nees"] for c in ok])
        pos = np.array([c["pos_err_m"] for c in ok])
        att = np.array([c["att_err_deg"] for c in ok])
        rel = pos / np.array([c["range_m"] for c in ok])
        gross = nees > GROSS_NEES
        good = nees[~gross]
        kg = max(len(good), 1)
        s.update(
            pos_err_m={"median": float(np.median(pos)), "p95": float(np.percentile(pos, 95))},
            pos_err_over_range={"median": float(np.median(rel)), "p95": float(np.percentile(rel, 95))},
            att_err_deg={"median": float(np.median(att)), "p95": float(np.percentile(att, 95))},
            gross_errors=int(gross.sum()),
            nees_mean=float(nees.mean()),
            nees_mean_without_gross=float(good.mean()) if len(good) else None,
            nees_mean_band95=[float(chi2.ppf(0.025, 6 * kg) / kg), float(chi2.ppf(0.975, 6 * kg) / kg)],
            nees_median=float(np.median(nees)),
            frac_nees_below_chi2_95=float(np.mean(nees < chi2.ppf(0.95, 6))),
        )
        lo, hi = s["nees_mean_band95"]
        s["nees_in_band"] = bool(lo <= (s["nees_mean_without_gross"] or 0.0) <= hi)
    s["by_range"] = by_range(cases)
    return s


def by_range(cases: list[dict], edges=RANGE_BINS_M) -> list[dict]:
    """Per range bin [lo, hi): cases, Ok poses, failures by reason and the
    mean NEES of the Ok poses without gross errors."""
    rows = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = [c for c in cases if lo <= c["range_m"] < hi]
        ok = [c["nees"] for c in sel if c["status"] == "Ok" and c["nees"] <= GROSS_NEES]
        fails = {}
        for c in sel:
            if c["status"] != "Ok":
                fails[c["status"]] = fails.get(c["status"], 0) + 1
        rows.append(
            {
                "range_m": [lo, hi],
                "cases": len(sel),
                "ok": sum(c["status"] == "Ok" for c in sel),
                "failures_by_reason": fails,
                "nees_mean_without_gross": float(np.mean(ok)) if ok else None,
            }
        )
    return rows


def image_campaign(
    seed: int, runs: int, conditions: dict | None = None, cam: cm.Camera | None = None, range_m=(0.3, 5.0)
) -> dict:
    cam = cm.Camera() if cam is None else cam
    conditions = cm.CONDITIONS if conditions is None else conditions
    est = cm.make_estimator(cam)
    rng_pose = np.random.default_rng(seed)
    rng_img = np.random.default_rng(seed + 1)
    per_cond = {name: [] for name in conditions}
    poses = []
    for i in range(runs):
        r, q, qh, d = cm.sample_pose(rng_pose, cam, range_m)
        poses.append({"r_hill_m": r, "q_hb": q, "q_h_host": qh, "range_m": d})
        for name, scene in conditions.items():
            c = run_case(est, r, q, qh, scene, rng_img, cam, t_s=float(i))
            c["run"] = i
            per_cond[name].append(c)
    summary = {name: summarise(cs) for name, cs in per_cond.items()}
    return {
        "seed": seed,
        "runs": runs,
        "range_m": list(range_m),
        "pixel_sigma_px": est.config.pixel_sigma_px,
        "summary": summary,
        "cases": per_cond,
    }


def distortion_experiment(seed: int, runs: int, k1_values=(0.0, -0.05, -0.1, -0.2, -0.3)) -> dict:
    """Distortion present in the lens, absent from the pipeline's model."""
    rng_pose = np.random.default_rng(seed + 100)
    rng_img = np.random.default_rng(seed + 101)
    pinhole = cm.Camera()
    est = cm.make_estimator(pinhole)  # assumes no distortion
    scene = cm.CONDITIONS["nominal"]
    poses = [cm.sample_pose(rng_pose, pinhole, (0.3, 5.0), margin_px=25.0) for _ in range(runs)]
    rows = []
    for k1 in k1_values:
        lens = cm.Camera(dist=np.array([k1, 0.0, 0.0, 0.0, 0.0]))
        meas, pred, statuses = [], [], []
        for r, q, qh, _ in poses:
            img = cm.render(r, q, qh, scene, rng_img, lens)
            m = est.estimate(img, 0.0, qh)
            statuses.append(m.status)
            if not m.ok:
                continue
            px_d = cm.led_pixels(r, q, qh, lens)[0]
            px_p = cm.led_pixels(r, q, qh, pinhole)[0]
            J = est.jacobian(r, q, qh)
            dx = np.linalg.lstsq(J, (px_d - px_p).reshape(-1), rcond=None)[0]
            meas.append(pose_error(m.r_hill_m, m.q_hb, r, q))
            pred.append(dx)
        meas, pred = np.array(meas).reshape(-1, 6), np.array(pred).reshape(-1, 6)
        row = {"k1": k1, "ok": len(meas), "failures": len(poses) - len(meas)}
        if len(meas):
            pm, pp = np.linalg.norm(meas[:, :3], axis=1), np.linalg.norm(pred[:, :3], axis=1)
            am, ap = np.degrees(np.linalg.norm(meas[:, 3:], axis=1)), np.degrees(np.linalg.norm(pred[:, 3:], axis=1))
            row.update(
                pos_err_m_median=float(np.median(pm)),
                pos_pred_m_median=float(np.median(pp)),
                att_err_deg_median=float(np.median(am)),
                att_pred_deg_median=float(np.median(ap)),
            )
            if abs(k1) > 0:
                # Slope and correlation of measured on predicted position error, all components pooled.
                x, y = pred[:, :3].ravel(), meas[:, :3].ravel()
                row["pos_slope_measured_on_predicted"] = float(x @ y / (x @ x))
                row["pos_correlation"] = float(np.corrcoef(x, y)[0, 1])
                x, y = pred[:, 3:].ravel(), meas[:, 3:].ravel()
                row["att_slope_measured_on_predicted"] = float(x @ y / (x @ x))
                row["att_correlation"] = float(np.corrcoef(x, y)[0, 1])
        rows.append(row)
    return {"runs": runs, "rows": rows}


def plots(result: dict, out_dir) -> list:
    from bench.report import matplotlib_agg, report_dir

    plt = matplotlib_agg()
    d = report_dir(out_dir)
    files = []
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for name, cases in result["images"]["cases"].items():
        ok = [c for c in cases if c["status"] == "Ok"]
        ax[0].scatter([c["range_m"] for c in ok], [c["pos_err_m"] for c in ok], s=6, label=name)
        ax[1].scatter([c["range_m"] for c in ok], [c["nees"] for c in ok], s=6, label=name)
    ax[0].set(xlabel="range [m]", ylabel="position error [m]", yscale="log")
    ax[1].axhline(chi2.ppf(0.95, 6), color="k", lw=0.8)
    ax[1].set(xlabel="range [m]", ylabel="NEES (6 dof)", yscale="log")
    ax[0].legend()
    fig.tight_layout()
    files.append(d / "pose_error_vs_range.png")
    fig.savefig(files[-1], dpi=120)
    plt.close(fig)
    if "distortion" in result:
        rows = [r for r in result["distortion"]["rows"] if "pos_err_m_median" in r]
        fig, ax = plt.subplots(figsize=(5, 4))
        k1 = [abs(r["k1"]) for r in rows]
        ax.plot(k1, [r["pos_err_m_median"] for r in rows], "o-", label="measured (median)")
        ax.plot(k1, [r["pos_pred_m_median"] for r in rows], "s--", label="predicted (median)")
        ax.set(xlabel="|k1| (unmodelled)", ylabel="position error [m]")
        ax.legend()
        fig.tight_layout()
        files.append(d / "pose_distortion.png")
        fig.savefig(files[-1], dpi=120)
        plt.close(fig)
    return [str(f) for f in files]
