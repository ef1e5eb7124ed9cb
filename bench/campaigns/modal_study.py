"""The `proxops modal` study (its command line: bench/commands/modal.py):
the modal estimator's trials (bench/campaigns/modal_campaign.py) run as a
campaign, and their summaries against the simulation and experiment of
"Shape, Motion, and Parameter Estimation of Large Flexible Space Structures
using Range Images" (Lichter and Dubowsky) and against each run's
references: the batch maximum-likelihood fit, the Cramer-Rao bounds, the
frequency acquisition and the coarse amplitudes' consistency; with the
first trial's figures."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.campaigns import modal_campaign as mc
from bench.report import matplotlib_agg
from bench.runner.runner import all_failed, failures, missing, results

# The paper's experiment: 20 trials converged to these (value, +- spread).
PAPER_OMEGA = [(4.31, 0.01), (8.68, 0.02)]
PAPER_ALPHA = [(0.049, 0.007), (0.143, 0.008)]


def run_trials(campaign, spec: dict, seed: int, n_trials: int, keep_first_series: bool) -> list:
    """Trials seed, seed + 1, ... as ``campaign`` (bench/runner): each a Dask
    task kept in the results store; the first keeps its series for the
    figures when ``keep_first_series``."""
    items = [{"seed": seed + k, "keep_series": bool(k == 0 and keep_first_series)} for k in range(n_trials)]
    recs = campaign.map("trial", mc.run_trial, items, shared=spec, label=f"modal {spec['scenario']}")
    all_failed(recs)
    for f in failures(recs):
        print(f"trial {f['run']} (seed {f['seed']}) failed: {f['error']}")
    if missing(recs):
        print(f"{len(missing(recs))} of {len(recs)} trials not stored: left out")
    trials = [r for r in results(recs) if r is not None]
    if not trials:
        raise ValueError("no finished trials")
    return trials


def summarise(trials: list, spec: dict) -> dict:
    """The study's answer for ``spec``'s scenario, printed as it is made."""
    return pendulum_summary(trials, spec) if spec["scenario"] == "pendulum" else structure_summary(trials, spec)


def plot(first_trial: dict, spec: dict, folder: Path) -> None:
    """The first trial's figures in ``folder``."""
    (plot_pendulum if spec["scenario"] == "pendulum" else plot_structure)(first_trial, folder)


def summary(vals):
    v = np.asarray(vals, float)
    return {
        "mean": float(v.mean()),
        "std": float(v.std(ddof=1)) if v.size > 1 else 0.0,
        "half_range": float((v.max() - v.min()) / 2),
        "min": float(v.min()),
        "max": float(v.max()),
    }


def pendulum_summary(trials: list, spec: dict) -> dict:
    """The quadruple-pendulum experiment analogue: the first two modes'
    frequencies and damping against the published ones."""
    out = {
        "scenario": "pendulum",
        "filter": spec["kwargs"]["kind"],
        "trials": [],
        "paper": {"omega_radps": PAPER_OMEGA, "alpha_ps": PAPER_ALPHA, "measurements_to_converge_max": 90},
    }
    for tr in trials:
        out["trials"].append({k: v for k, v in tr.items() if k not in ("t_s", "est", "coarse", "truth")})
    for i in range(2):
        out[f"omega{i + 1}"] = summary([t["omega_final_radps"][i] for t in trials])
        out[f"alpha{i + 1}"] = summary([t["alpha_final_ps"][i] for t in trials])
    nc = [t["measurements_to_converge"] for t in trials]
    out["measurements_to_converge_max"] = None if any(v is None for v in nc) else int(max(nc))
    for i in range(2):
        w, a = out[f"omega{i + 1}"], out[f"alpha{i + 1}"]
        print(
            f"mode {i + 1}: omega {w['mean']:.4f} +- {w['std']:.4f} (half-range {w['half_range']:.4f}) rad/s "
            f"[paper {PAPER_OMEGA[i][0]} +- {PAPER_OMEGA[i][1]}];  alpha {a['mean']:.4f} +- {a['std']:.4f} "
            f"(half-range {a['half_range']:.4f}) 1/s [paper {PAPER_ALPHA[i][0]} +- {PAPER_ALPHA[i][1]}]"
        )
    print(f"measurements to converge (max over trials): {out['measurements_to_converge_max']} (paper < 90)")
    return out


def structure_summary(trials: list, spec: dict) -> dict:
    """The plate simulation: convergence of frequencies and shapes per trial,
    with the optional references (batch ML, Cramer-Rao bounds, acquisition)."""
    kw = spec["kwargs"]
    out = {
        "scenario": "structure",
        "filter": kw["kind"],
        "modes": kw["n_modes"],
        "range_noise": kw["noise_frac"],
        "points_at": kw["points_at"],
        "trials": [],
    }
    for tr in trials:
        out["trials"].append({k: v for k, v in tr.items() if k not in ("t_s", "est", "coarse", "truth")})
        n1, p1 = tr["measurements_to_converge_1pct"], tr["time_to_converge_1pct_periods"]
        px, ps = tr["time_to_converge_1pct_excited_periods"], tr["shape_converge_periods"]
        print(
            f"seed {tr['seed']}: all frequencies within 1 % "
            f"{'never' if n1 is None else f'after {n1} images ({_fmt(p1)} lowest-mode periods)'}; "
            f"those of the modes excited >= 0.2 {'never' if px is None else f'after {_fmt(px)} periods'}; "
            f"final max relative error {tr['freq_rel_err_final_max']:.2e}; shape RMS at its floor "
            f"({tr['shape_noise_floor_m']:.2f} m) {'never' if ps is None else f'after {_fmt(ps)} periods'}; "
            f"median cond(M_Y) {tr['condition_number_median']:.1f}"
        )
    if kw["batch_ml_periods"]:
        out["batch_ml_summary"] = batch_ml_summary(trials)
    if kw["crb_periods"]:
        out["crb_summary"] = crb_summary(trials)
    if kw["acquire_periods"] is not None:
        out["acquisition_summary"] = acquisition_summary(trials)
    if kw["coarse_check"]:
        out["coarse_check_summary"] = coarse_check_summary(trials, kw["n_modes"], kw["points_at"])
    out["ill_conditioned_cases"] = mc.plate_aliased_case(kw["n_modes"])
    print(
        "ill-conditioned cases: "
        + "; ".join(
            f"{name.replace('_', ' ')}: {case['status'].replace('_', ' ')} ({case['n_used']} points used"
            + (f", condition number {case['condition_number']:.3g}" if "condition_number" in case else "")
            + ")"
            for name, case in out["ill_conditioned_cases"].items()
        )
    )
    return out


def batch_ml_summary(trials):
    """Per requested time, medians over trials of the shape error of the filter,
    the batch ML reference and the known-frequency filter, each also over the
    trial's floor; and how many trials are within twice the floor."""
    rows = []
    for j, first in enumerate(trials[0]["batch_ml"]):
        r = {"periods": first["periods"], "images": first["images"], "trials": len(trials)}
        for key, name in (
            ("shape_rms_filter_m", "filter"),
            ("shape_rms_batch_ml_m", "batch_ml"),
            ("shape_rms_known_omega_m", "known_omega"),
        ):
            v = np.array([t["batch_ml"][j][key] for t in trials])
            floor = np.array([t["shape_noise_floor_m"] for t in trials])
            r[f"{name}_median_m"] = float(np.median(v))
            r[f"{name}_over_floor_median"] = float(np.median(v / floor))
            r[f"{name}_within_2x_floor"] = int(np.sum(v <= 2.0 * floor))
        ratio = np.array(
            [t["batch_ml"][j]["shape_rms_filter_m"] / t["batch_ml"][j]["shape_rms_batch_ml_m"] for t in trials]
        )
        r["filter_over_batch_ml_median"] = float(np.median(ratio))
        r["filter_over_batch_ml_quartiles"] = [float(q) for q in np.percentile(ratio, [25, 75])]
        c = [t["batch_ml"][j] for t in trials]
        r["excited_modes"] = int(sum(x["n_excited"] for x in c))
        for name in ("filter", "batch_ml"):
            r[f"{name}_excited_within_1pct"] = int(sum(x[f"excited_within_1pct_{name}"] for x in c))
            r[f"{name}_runs_all_excited_within_1pct"] = int(
                sum(x[f"excited_within_1pct_{name}"] == x["n_excited"] for x in c)
            )
        r["from_truth_excited_within_1pct"] = int(sum(x["from_truth_excited_within_1pct"] for x in c))
        # runs where the optimum reached from the true frequencies is lower (by more than 1e-6
        # relative) than the estimator's: its own starts missed the data's better optimum
        r["runs_better_optimum_near_truth"] = int(
            sum(x["from_truth_cost"] < x["batch_ml_cost"] * (1 - 1e-6) for x in c)
        )
        rows.append(r)
        print(
            f"at {r['periods']:.2f} periods ({r['images']} images), medians over {len(trials)} trials: shape RMS "
            f"filter {r['filter_median_m']:.3f} m ({r['filter_over_floor_median']:.2f} x floor), batch ML "
            f"{r['batch_ml_median_m']:.3f} m ({r['batch_ml_over_floor_median']:.2f} x), known omega "
            f"{r['known_omega_median_m']:.3f} m ({r['known_omega_over_floor_median']:.2f} x); filter / batch ML "
            f"{r['filter_over_batch_ml_median']:.2f} [{r['filter_over_batch_ml_quartiles'][0]:.2f}, "
            f"{r['filter_over_batch_ml_quartiles'][1]:.2f}]; within 2x floor: filter {r['filter_within_2x_floor']}, "
            f"batch ML {r['batch_ml_within_2x_floor']}, known omega {r['known_omega_within_2x_floor']}; excited "
            f"modes within 1 %: filter {r['filter_excited_within_1pct']}, batch ML {r['batch_ml_excited_within_1pct']}, "
            f"from the true frequencies {r['from_truth_excited_within_1pct']} of {r['excited_modes']}; runs with a "
            f"lower optimum near the truth than the batch ML found: {r['runs_better_optimum_near_truth']}"
        )
    return rows


def crb_summary(trials):
    """Per requested time, the filter beside its run's Cramer-Rao bounds:
    excited modes within 1 % (filter's count, the bound's expectation), runs
    with every excited mode within 1 % (filter's count, the bound's expected
    count), and shape RMS medians (filter, bound with frequencies unknown,
    known-frequency filter, bound with frequencies known), each also over the
    run's floor."""
    rows = []
    for j, first in enumerate(trials[0]["crb"]):
        c = [t["crb"][j] for t in trials]
        floor = np.array([t["shape_noise_floor_m"] for t in trials])
        r = {
            "periods": first["periods"],
            "images": first["images"],
            "trials": len(trials),
            "excited_modes": int(sum(x["n_excited"] for x in c)),
            "filter_excited_within_1pct": int(sum(x["filter_excited_within_1pct"] for x in c)),
            "crb_expected_excited_within_1pct": float(sum(x["crb_expected_excited_within_1pct"] for x in c)),
            "filter_runs_all_excited_within_1pct": int(
                sum(x["filter_excited_within_1pct"] == x["n_excited"] for x in c)
            ),
            "crb_expected_runs_all_excited_within_1pct": float(sum(x["crb_p_all_excited_within_1pct"] for x in c)),
        }
        for key, name in (
            ("shape_rms_filter_m", "filter"),
            ("crb_shape_rms_m", "crb"),
            ("shape_rms_known_omega_m", "known_omega"),
            ("crb_shape_rms_known_omega_m", "crb_known"),
        ):
            v = np.array([x[key] for x in c])
            r[f"{name}_median_m"] = float(np.median(v))
            r[f"{name}_over_floor_median"] = float(np.median(v / floor))
            r[f"{name}_within_2x_floor"] = int(np.sum(v <= 2.0 * floor))
        # against the known-frequency filter at the same image: a floor that does not move with the run length
        known = np.array([x["shape_rms_known_omega_m"] for x in c])
        r["filter_within_2x_known_same_image"] = int(
            np.sum(np.array([x["shape_rms_filter_m"] for x in c]) <= 2.0 * known)
        )
        r["crb_within_2x_known_same_image"] = int(np.sum(np.array([x["crb_shape_rms_m"] for x in c]) <= 2.0 * known))
        # efficiency: the filter's mean squared shape error over the bound's (1 for an efficient estimator)
        r["filter_over_crb_rms"] = float(
            np.sqrt(
                np.mean([x["shape_rms_filter_m"] ** 2 for x in c]) / np.mean([x["crb_shape_rms_m"] ** 2 for x in c])
            )
        )
        rows.append(r)
        print(
            f"at {r['periods']:.2f} periods ({r['images']} images), {len(trials)} runs: excited modes within 1 %: "
            f"filter {r['filter_excited_within_1pct']} of {r['excited_modes']}, bound expects "
            f"{r['crb_expected_excited_within_1pct']:.1f}; runs with all within 1 %: filter "
            f"{r['filter_runs_all_excited_within_1pct']}, bound expects "
            f"{r['crb_expected_runs_all_excited_within_1pct']:.1f}; shape RMS medians filter "
            f"{r['filter_median_m']:.3f} m ({r['filter_over_floor_median']:.2f} x floor), bound "
            f"{r['crb_median_m']:.3f} m ({r['crb_over_floor_median']:.2f} x), known omega "
            f"{r['known_omega_median_m']:.3f} m, its bound {r['crb_known_median_m']:.3f} m; within 2x floor: "
            f"filter {r['filter_within_2x_floor']}, bound {r['crb_within_2x_floor']}; within 2x the known-frequency "
            f"filter at that image: filter {r['filter_within_2x_known_same_image']}, bound "
            f"{r['crb_within_2x_known_same_image']}; RMS over runs, filter / bound {r['filter_over_crb_rms']:.2f}"
        )
    return rows


def acquisition_summary(trials):
    """Acquisition then filter, beside the one-pass filter: excited modes
    within 1 %, runs with all of them, and runs with the shape within 2x the
    noise floor, per scored time."""
    rows = []
    first = trials[0]["acquisition"]
    n_exc = [int(np.sum(np.asarray(t["amp_true"]) >= 0.2)) for t in trials]
    for j, at in enumerate(first["at"]):
        a = [t["acquisition"]["at"][j] for t in trials]
        r = {
            "method": first["method"],
            "periods": at["periods"],
            "images": at["images"],
            "trials": len(trials),
            "acquired_at_periods": first["periods"],
            "excited_modes": int(sum(n_exc)),
            "search_excited_within_1pct": int(sum(t["acquisition"]["search_excited_within_1pct"] for t in trials)),
            "excited_within_1pct": int(sum(x["excited_within_1pct"] for x in a)),
            "runs_all_excited_within_1pct": int(sum(x["excited_within_1pct"] == n for x, n in zip(a, n_exc))),
            "shape_rms_median_m": float(np.median([x["shape_rms_m"] for x in a])),
        }
        if all("shape_noise_floor_m" in t for t in trials):
            ratio = [x["shape_rms_m"] / t["shape_noise_floor_m"] for x, t in zip(a, trials)]
            r["shape_x_floor_median"] = float(np.median(ratio))
            r["runs_shape_within_2x_floor"] = int(sum(v <= 2.0 for v in ratio))
        known = np.array([x["shape_rms_known_omega_m"] for x in a])
        if np.all(np.isfinite(known)):
            r["runs_shape_within_2x_known_same_image"] = int(
                np.sum(np.array([x["shape_rms_m"] for x in a]) <= 2.0 * known)
            )
        if r["method"] == "flight":
            r["search_s_median"] = float(np.median([t["acquisition"]["search_s"] for t in trials]))
            r["replay_s_median"] = float(np.median([t["acquisition"]["replay_s"] for t in trials]))
        rows.append(r)
        print(
            f"acquisition ({r['method']}) at {r['acquired_at_periods']:.2f} periods (search alone: "
            f"{r['search_excited_within_1pct']} of {r['excited_modes']} excited within 1 %), then the flight joint "
            f"filter, at {r['periods']:.2f} periods: excited within 1 % {r['excited_within_1pct']} of "
            f"{r['excited_modes']}, runs with all {r['runs_all_excited_within_1pct']} of {len(trials)}, shape RMS "
            f"median {r['shape_rms_median_m']:.3f} m"
            + (
                f" ({r['shape_x_floor_median']:.2f} x floor), within 2x floor in {r['runs_shape_within_2x_floor']} runs"
                if "runs_shape_within_2x_floor" in r
                else ""
            )
            + (
                f", within 2x the known-frequency filter at that image in {r['runs_shape_within_2x_known_same_image']}"
                if "runs_shape_within_2x_known_same_image" in r
                else ""
            )
        )
    return rows


def coarse_check_summary(trials, m, points_at):
    """Pooled over every image of every run: NEES mean against M (its
    standard error from the chi-square's 2M variance), and per mode the mean
    error in reported sigmas with its standard error."""
    cc = [t["coarse_check"] for t in trials]
    nees = np.concatenate([np.asarray(c["nees"]) for c in cc])
    n = int(sum(c["images"] for c in cc))
    z_mean = sum(np.asarray(c["z_mean"]) * c["images"] for c in cc) / n
    z_sd = np.sqrt(np.maximum(sum(np.asarray(c["z_sq_sum"]) for c in cc) / n - z_mean**2, 0.0))
    se = z_sd / np.sqrt(n)
    biased = np.nonzero(np.abs(z_mean) > 4 * se)[0]
    worst = int(np.argmax(np.abs(z_mean)))
    r = {
        "points_at": points_at,
        "images": n,
        "nees_mean": float(nees.mean()),
        "nees_expected": m,
        "nees_mean_se": float(np.sqrt(2 * m / n)),
        "bias_sigma": z_mean.tolist(),
        "spread_sigma": z_sd.tolist(),
        "modes_biased_4se": [int(i) + 1 for i in biased],
        "worst_mode": worst + 1,
        "worst_bias_sigma": float(z_mean[worst]),
    }
    print(
        f"coarse amplitudes vs truth (mode shapes at the {points_at} point), {n} images: NEES mean "
        f"{r['nees_mean']:.2f} (expected {m} +- {r['nees_mean_se']:.2f}); modes biased beyond 4 standard errors: "
        f"{len(biased)} of {m}, the largest {r['worst_bias_sigma']:+.2f} sigma (mode {worst + 1})"
    )
    return r


def _fmt(v):
    return "never" if v is None else f"{v:.2f}"


def plot_pendulum(tr, folder: Path):
    plt = matplotlib_agg()
    t, est, coarse = tr["t_s"], tr["est"], tr["coarse"]
    fig, ax = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for i in range(3):
        ax[i].plot(t, coarse[:, i], "k-", lw=0.8, label="coarse A~ (eq. 3)")
        ax[i].plot(t, est[:, i, 0], color="0.6", lw=2, label="filtered A^")
        ax[i].set_ylabel(f"mode {i + 1} [m]")
    ax[0].legend(loc="upper right")
    ax[-1].set_xlabel("time [s]")
    fig.suptitle("Pendulum: coarse and filtered modal coefficients (cf. seed Fig. 9)")
    fig.savefig(folder / "modal_pendulum_fig9.png", dpi=110)
    fig, ax = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    for i, (w, a) in enumerate(zip([4.31, 8.68], [0.049, 0.143])):
        ax[0].plot(t, est[:, i, 2])
        ax[0].axhline(w, ls=":", color="k")
        ax[1].plot(t, est[:, i, 3])
        ax[1].axhline(a, ls=":", color="k")
    ax[0].set_ylabel("omega [rad/s]")
    ax[1].set_ylabel("alpha [1/s]")
    ax[1].set_xlabel("time [s]")
    fig.savefig(folder / "modal_pendulum_params.png", dpi=110)
    plt.close("all")


def plot_structure(tr, folder: Path):
    plt = matplotlib_agg()
    t = tr["t_s"] / 60.0
    est, coarse = tr["est"], tr["coarse"]
    m = est.shape[1]
    show = sorted({0, 1, m // 2, m - 1})
    fig, ax = plt.subplots(len(show), 1, figsize=(8, 2 * len(show)), sharex=True)
    for a, i in zip(ax, show):
        a.plot(t, coarse[:, i], "k-", lw=0.8)
        a.plot(t, est[:, i, 0], color="0.6", lw=2)
        a.set_ylabel(f"A{i + 1}")
    ax[-1].set_xlabel("time [min]")
    fig.suptitle(f"Plate, {m} modes: coarse (black) and filtered (grey) coefficients (cf. seed Fig. 4)")
    fig.savefig(folder / f"modal_structure{m}_fig4.png", dpi=110)
    fig, a = plt.subplots(figsize=(8, 4))
    a.plot(t, est[:, :, 2] / np.asarray(tr["omega_true_radps"])[None, :], lw=0.8)
    a.axhline(1.0, ls=":", color="k")
    a.set_ylim(0.8, 1.2)
    a.set_xlabel("time [min]")
    a.set_ylabel("omega^ / omega")
    a.set_title(f"Frequency estimates, {m} modes (cf. seed Fig. 5)")
    fig.savefig(folder / f"modal_structure{m}_fig5.png", dpi=110)
    fig, a = plt.subplots(figsize=(8, 4))
    a.semilogy(np.arange(len(t)), tr["shape_rms_m"], label="estimator")
    a.semilogy(np.arange(len(t)), tr["shape_rms_oracle_m"], label="known omega (floor)")
    a.semilogy(np.arange(len(t)), tr["shape_sigma_m"], ls="--", label="eq. 9 1-sigma (RMS)")
    a.set_xlabel("measurement")
    a.set_ylabel("shape RMS error [m]")
    a.legend()
    a.set_title(f"Shape error over the whole plate, {m} modes (cf. seed Fig. 6)")
    fig.savefig(folder / f"modal_structure{m}_fig6.png", dpi=110)
    plt.close("all")
