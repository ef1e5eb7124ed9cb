"""The diagnosis page: Markdown with plots, readable in two minutes."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.gap import localise
from bench.report import matplotlib_agg

CH = ("r_x", "r_y", "r_z", "th_x", "th_y", "th_z")


def _gap_map_png(cells, path: Path):
    plt = matplotlib_agg()
    rows = [(s, a) for s, _, _ in localise.STREAMS for a in "xyz"] + [
        (s, a) for s, _ in localise.DYN_STREAMS for a in "xyz"]
    cols = [(r, st) for r in localise.REGIMES for st in localise.STATS
            if r == "all" or st in ("mean", "variance")]
    z = np.full((len(rows), len(cols)), np.nan)
    for c in cells:
        i = rows.index((c["stream"], c["axis"]))
        if (c["regime"], c["stat"]) in cols:
            z[i, cols.index((c["regime"], c["stat"]))] = c["z"]
    fig, ax = plt.subplots(figsize=(10, 5.0))
    lim = max(4.0, float(np.nanmax(np.abs(z))) if np.isfinite(z).any() else 4.0)
    im = ax.imshow(z, cmap="RdBu_r", vmin=-lim, vmax=lim, aspect="auto")
    short = {"pose position": "pose pos", "pose attitude": "pose att", "imu accel vs valves": "accel-valves",
             "gyro vs valve torques": "gyro-torques"}
    ax.set_yticks(range(len(rows)), [f"{short[s]} {a}" for s, a in rows])
    ax.set_xticks(range(len(cols)), [f"{r}\n{s}" for r, s in cols], fontsize=7)
    for i in range(z.shape[0]):
        for j in range(z.shape[1]):
            if np.isfinite(z[i, j]):
                ax.text(j, i, f"{z[i, j]:.1f}", ha="center", va="center", fontsize=6)
    fig.colorbar(im, ax=ax, label="z (N(0,1) under the null)")
    ax.set_title("Gap map: whitened residuals by stream, axis, regime and statistic")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _residuals_png(t, before, after, held, label, path: Path):
    plt = matplotlib_agg()
    fig, ax = plt.subplots(6, 2, figsize=(11, 10), sharex="col")
    for i in range(6):
        a = ax[i, 0]
        a.plot(t, before[:, i], ".", ms=3, color="0.5", label="nominal")
        if after is not None:
            a.plot(t, after[:, i], ".", ms=3, color="C3", label=f"with {label}")
        a.axhline(0, color="k", lw=0.5)
        a.set_ylabel(f"{CH[i]} (whitened)")
        for t0, t1 in _spans(t, held):
            a.axvspan(t0, t1, color="C0", alpha=0.08, lw=0)
        b = ax[i, 1]
        ok = np.isfinite(before[:, i])
        f = np.fft.rfftfreq(int(ok.sum()), 1.0)[1:]
        b.semilogy(f, (np.abs(np.fft.rfft(before[ok, i])) ** 2 / ok.sum())[1:], color="0.5")
        if after is not None:
            b.semilogy(f, (np.abs(np.fft.rfft(after[ok, i])) ** 2 / ok.sum())[1:], color="C3")
        b.axhline(1.0, color="k", lw=0.5, ls=":")
    ax[0, 0].legend(loc="upper right", fontsize=7)
    ax[-1, 0].set_xlabel("capture time [s] (shaded: held-out blocks)")
    ax[-1, 1].set_xlabel("frequency [Hz] (periodogram; 1 = white)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _spans(t, mask):
    out, start = [], None
    for ti, m in zip(t, mask):
        if m and start is None:
            start = ti
        if not m and start is not None:
            out.append((start, ti))
            start = None
    if start is not None:
        out.append((start, t[-1]))
    return out


def write_report(result: dict, out_dir, log_name: str = "log") -> Path:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    it = result["_internal"]
    d, nominal, held = it["d"], it["nominal"], it["held"]
    _gap_map_png(it["cells"], out / "gap_map.png")
    best = result["attribution"][0] if result["attribution"] else None
    after = None
    if best is not None:
        f = next(x for x in it["fits"] if x.name == best["effect"])
        after = f.after_nav.white
    _residuals_png(d.pose_tc, nominal.white, after, held, best["effect"] if best else "", out / "residuals.png")

    st = result["statistics"]
    loc = result["location"]
    w = loc["where"] or {}
    lines = [f"# Gap diagnosis: {log_name}", ""]
    lines += ["## The three answers", ""]
    if not result["gap_detected"]:
        lines.append("**No gap detected**: the log is consistent with the nominal model at the calibrated "
                     f"false-alarm rate ({st['false_alarm_rate']}).")
    else:
        lines.append(f"- **Where**: {w.get('stream')} axis {w.get('axis')} ({w.get('frame')}), statistic "
                     f"`{w.get('stat')}`, strongest while {w.get('regime_peak')}; a **{loc['dynamics_or_sensor']}** gap.")
        acts = loc.get("effect_acts_while")
        if acts and acts["peak"]:
            lines.append(f"- The fitted effect acts mostly while **{acts['peak']}** (its signature's energy per row: "
                         + ", ".join(f"{r} {v:.3g}" for r, v in acts["energy_per_row"].items()) + ").")
        if result["verdict"] == "unexplained":
            lines.append("- **Which**: **unexplained**: no effect in the library accounts for the gap on held-out data.")
        else:
            amb = ", ".join(a["effect"] for a in result["ambiguous_with"])
            lines.append(f"- **Which**: **{best['effect']}** ({result['verdict']}"
                         + (f"; cannot be told apart from {amb}" if amb else "") + ")")
        if best is not None:
            sh = best["shrink_heldout"]
            lines.append(f"- **How far**: adding {best['effect']} shrinks the held-out deficit by "
                         f"{100 * sh['fraction']:.0f} % (95 % CI {100 * sh['ci95'][0]:.0f} to {100 * sh['ci95'][1]:.0f} %).")
            rr = result.get("shrink_heldout_runs")
            if rr and rr.get("fraction") is not None and np.isfinite(rr["fraction"]):
                lines.append(f"  On held-out runs ({rr['heldout_runs']} of the log's {rr['runs']} chained runs, the "
                             f"effect fitted on the others): {100 * rr['fraction']:.0f} % (95 % CI "
                             f"{100 * rr['ci95'][0]:.0f} to {100 * rr['ci95'][1]:.0f} %).")
            elif rr:
                why = rr.get("reason", "no deficit left on the held-out runs to shrink")
                lines.append(f"  Held-out runs: not measured ({why}).")
    lines += ["", f"Detection: gap-map max |z| = {st['map_max_abs_z']:.2f} (threshold {st['map_threshold']:.2f}); "
              f"best screening -log10 p = {st['screen_logp_max']:.2f} (threshold {st['screen_logp_threshold']:.2f}); "
              f"thresholds from {st['calibration_runs']} null runs, false-alarm rate {st['false_alarm_rate']}.", ""]
    if result["ambiguous_with"]:
        lines += ["### Not told apart", ""]
        for a in result["ambiguous_with"]:
            lines.append(f"- {best['effect']} vs {a['effect']} (ln Bayes factor difference {a['ln_bf_difference']:.1f}; "
                         f"{a['effect']} reproduces {best['effect']}'s fitted signature to within "
                         f"{a['signature_distance2']:.1f} noise variances): "
                         f"separate with: {a['separate_by']}")
        lines.append("")
    lines += ["## Ranking (confirmed by full-filter refit on training blocks)", "",
              "| effect | kind | ln Bayes factor | BIC | dLL train | dLL held-out | shrink held-out [95 % CI] | explains | parameters |",
              "|---|---|---|---|---|---|---|---|---|"]
    for r in result["attribution"]:
        sh = r["shrink_heldout"]
        pars = "; ".join(f"{k} = {v['value']:.3g} +/- {v['sigma']:.2g}" for k, v in r["parameters"].items())
        lines.append(f"| {r['effect']} | {r['kind']} | {r['evidence']['ln_bf']:.1f} | {r['evidence']['bic']:.1f} | {r['evidence']['dll_train']:.1f} | "
                     f"{r['evidence']['dll_heldout']:.1f} | {sh['fraction']:.2f} [{sh['ci95'][0]:.2f}, {sh['ci95'][1]:.2f}] | "
                     f"{'yes' if r['explains_heldout'] else 'no'} | {pars} |")
    lines += ["", "Screening (linearised GLR, every candidate, -log10 p against chi-square(rank)): " + ", ".join(
        f"{s['effect']} {s['screen_logp']:.1f}" for s in result["screening"]), ""]
    lines += ["## Gap map", "", "![gap map](gap_map.png)", "",
              "Top cells (family-wise p-values against the null's largest |z|):", ""]
    for c in loc["top_cells"]:
        lines.append(f"- {c['stream']} {c['axis']} {c['regime']} {c['stat']}: z = {c['z']:.2f}"
                     + (f", p {'<=' if c.get('p_beyond_null') else '='} {c['p_familywise']:.3f}"
                        if "p_familywise" in c else ""))
    lines += ["", "## Residuals and spectra, before and after", "", "![residuals](residuals.png)", "",
              "Replay RMS per channel on held-out blocks (nominal): " + ", ".join(
                  f"{k} {v:.3g}" for k, v in result["replay_rms_heldout_before"].items())]
    if best is not None:
        lines.append("; with the best candidate: " + ", ".join(
            f"{k} {v:.3g}" for k, v in best["replay_rms_heldout_after"].items()))
    lines += ["", f"In the library but without a candidate model yet: {', '.join(result['not_modelled'])}.", "",
              f"Log: {result['log']['duration_s']:.0f} s, {result['log']['pose_updates']} pose updates "
              f"({result['log']['train_updates']} train / {result['log']['heldout_updates']} held out); "
              f"diagnosed in {result['elapsed_s']:.1f} s."]
    p = out / "README.md"
    p.write_text("\n".join(lines) + "\n")
    return p
