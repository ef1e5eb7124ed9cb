"""The diagnosis page: Markdown with plots, readable in two minutes."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.gap import localise
from bench.gap.answers import at_bound, counted_text, identified, not_identified_count, significant
from bench.gap.candidates import candidates_of
from bench.gap.report_plots import gap_map_figure, residuals_figure, save

CH = ("r_x", "r_y", "r_z", "th_x", "th_y", "th_z")


def _where_stream(result: dict):
    """The stream of the gap map's largest cell, or None (no gap located)."""
    where = (result.get("location") or {}).get("where") or {}
    return where.get("stream")


def residual_series(result: dict) -> tuple:
    """The channels where the gap map found the gap (else those the named
    effect acts on), before and after the effect: the pose innovations, or
    the accelerometer and gyro against the valve model."""
    it = result["_internal"]
    d, nominal, held, ctx = it["d"], it["nominal"], it["held"], it["ctx"]
    best = result["attribution"][0] if result["attribution"] and result["verdict"] != "unexplained" else None
    fit = next(x for x in it["fits"] if x.name == best["effect"]) if best else None
    names = [fit.name] if fit is not None else []
    es = result.get("effect_set")
    if es and (es.get("explains_heldout") or result["verdict"] == "partly_explained"):
        from bench.gap.select import as_fit

        fit, names = as_fit(es["_fit"]), [m["effect"] for m in es["members"]]
    if _where_stream(result) is not None:  # the channel where the gap map found the gap
        nav = ctx.ch is None or _where_stream(result) not in {s for s, _ in localise.DYN_STREAMS}
    else:
        nav = fit is None or any(candidates_of(d)[n].nav for n in names) or ctx.ch is None
    if nav:
        after = fit.after_nav.white if fit is not None else None
        series = [
            (
                f"{CH[i]} (whitened)",
                d.pose_tc,
                nominal.white[:, i],
                None if after is None else after[:, i],
                held,
                float(np.median(np.diff(d.pose_tc))) if d.pose_tc.size > 1 else 1.0,
            )
            for i in range(6)
        ]
        return series, "pose innovations (whitened)"
    ch = ctx.ch
    series = []
    for kind, name in ((0, "accel"), (1, "gyro diff")):
        m = ch.kind == kind
        hd = ctx.held_dyn[m] if ctx.held_dyn is not None else np.zeros(int(m.sum()), bool)
        for i, ax in enumerate("xyz"):
            series.append(
                (
                    f"{name} {ax}",
                    ch.t[m],
                    ch.e0[m, i],
                    fit.after_dyn[m, i] if fit is not None and fit.after_dyn is not None else None,
                    hd,
                    d.dt_s,
                )
            )
    return series, "accelerometer and gyro against the valve model (whitened rows)"


def _not_told_apart_lines(result: dict, best) -> list:
    """The sets or effects the data could not tell apart, and what would."""
    lines = []
    if not result["ambiguous_with"]:
        return lines
    lines += ["### Not told apart", ""]
    for a in result["ambiguous_with"]:
        if "add" in a:  # one more member the data cannot rule out
            lines.append(
                f"- {' + '.join(a['set'])}: {a['add']} can carry {a['hidden_signature2']:.0f} noise variances of "
                f"the gap beside {' + '.join(a['to'])}, whose members absorb it to within "
                f"{a['signature_distance2']:.1f}: separate with: {a['separate_by']}"
            )
            continue
        if "part_of_gap" in a:  # an unexplained answer's in-library part
            lines.append(
                f"- {' + '.join(a['set'])}: gains on the held-out data, but the set fails another held-out "
                f"test; it may sit beside what the library lacks: separate with: {a['separate_by']}"
            )
            continue
        if "drop" in a:  # a partial answer without one member
            lines.append(
                f"- {' + '.join(a['set']) or 'none'}: {a['drop']}'s fit may be the remainder's shadow in the library: "
                f"separate with: {a['separate_by']}"
            )
            continue
        if "logp_beside" in a:  # a set that explains what the answer explains
            lines.append(
                f"- {' + '.join(a['set'])}: the answer's members beside it add -log10 p = {a['logp_beside']:.1f} "
                f"(below the screening threshold): separate with: {a['separate_by']}"
            )
            continue
        if "replace" in a:  # a set with one member swapped for a look-alike
            lines.append(
                f"- {' + '.join(a['set'])}: {a['with']} in place of {a['replace']} reproduces the set's "
                f"fitted signature to within {a['signature_distance2']:.1f} noise variances: "
                f"separate with: {a['separate_by']}"
            )
            continue
        lines.append(
            f"- {best['effect']} vs {a['effect']} (ln Bayes factor difference {a['ln_bf_difference']:.1f}; "
            f"{a['effect']} reproduces {best['effect']}'s fitted signature to within "
            f"{a['signature_distance2']:.1f} noise variances): "
            f"separate with: {a['separate_by']}"
        )
    lines.append("")
    return lines


# A candidate with more parameters than this shows in the ranking table only
# those beyond 2 sigma (the largest first); all of them are listed below it.
TABLE_PARAMETERS = 4


def _parameter_text(k: str, v: dict) -> str:
    """One parameter: its value and sigma; held at a physical bound
    (answers.at_bound), the bound and no sigma; or, when the data do not
    identify it (answers.identified), no value: "not identifiable" when the
    log cannot identify it at all, "not identified" with its sigma when that
    exceeds the candidate's physical bound."""
    if at_bound(v):
        b = v.get("bound")
        return f"{k} = {(b if b is not None else v['value']):.3g}, at its {v['at_bound']} bound (no sampling sigma)"
    if identified(v):
        return f"{k} = {v['value']:.3g} +/- {v['sigma']:.2g}"
    if v.get("value") is None:
        return f"{k}: not identifiable"
    return f"{k}: not identified (sigma {v['sigma']:.2g} beyond the physical bound)"


def _parameters_cell(params: dict) -> str:
    """A ranking-table cell: every parameter, or for a long list the ones
    beyond 2 sigma, the most significant first, and how many the data do
    not identify and how many the fit holds at a bound."""
    n_not = not_identified_count(params)
    if len(params) <= TABLE_PARAMETERS:
        return "; ".join(_parameter_text(k, v) for k, v in params.items())
    big = [(abs(v["value"]) / v["sigma"], k, v) for k, v in params.items() if significant(v)]
    big.sort(key=lambda x: -x[0])
    shown = "; ".join(_parameter_text(k, v) for _, k, v in big[:TABLE_PARAMETERS])
    n_bound = sum(at_bound(v) for v in params.values())
    return (
        f"{len(big)} of {len(params)} beyond 2 sigma"
        + (f", {n_not} not identified" if n_not else "")
        + (f", {n_bound} at a bound" if n_bound else "")
        + (f": {shown}" if shown else "")
        + " (all below)"
    )


def _every_parameter_lines(label: str, params: dict) -> list:
    """A long parameter list in full, below the table whose cell shows only
    the ones beyond 2 sigma (_parameters_cell), with how many the data do
    not identify."""
    lines = ["", f"{label}, every parameter{counted_text(params)}:", ""]
    return lines + [f"- {_parameter_text(k, v)}" for k, v in params.items()]


def _set_status(result: dict, es: dict) -> str:
    """What the jointly fitted set is to the answer."""
    v = result["verdict"]
    if es.get("explains_heldout"):
        return "The answer: refitted together, the set explains the held-out data."
    if v == "partly_explained":
        each = "each member earns its place" if len(es["members"]) > 1 else "it earns its place"
        return (
            f"The partial answer: {each} on the held-out data; a remainder no effect in the library accounts for stays."
        )
    if v in ("explained", "ambiguous") and result["attribution"]:
        best = result["attribution"][0]["effect"]
        return (
            f"Not the answer ({best} alone is): the set's refit does not pass the held-out tests, "
            f"or does not beat {best} there."
        )
    return (
        "Not an answer: the set's refit does not pass the held-out tests, so the gap stays unexplained "
        "and no value below is an answer."
    )


def _set_lines(result: dict) -> list:
    """The set of effects forward selection chose (``effect_set``), when it
    chose one: what it is to the answer, its held-out scores, each member's
    share and its jointly fitted parameters, as the ranking shows a single
    candidate's (_parameters_cell), and how many the data do not identify."""
    es = result.get("effect_set")
    if not es or not es.get("members"):
        return []
    members = es["members"]
    thr = result["statistics"]["map_threshold"]
    shares = (
        " Each member adds what the set loses on the held-out data with its parameters set to zero, the others kept."
        if len(members) > 1
        else ""
    )
    lines = [
        f"## The selected set: {' + '.join(m['effect'] for m in members)}",
        "",
        _set_status(result, es),
        "",
        f"On the held-out data: shrink {_shrink_cell(es['shrink_heldout'])}, log-likelihood "
        f"{es['dll_heldout']:+.1f}; gap-map max |z| after the fit {es['map_max_abs_z_after']:.2f} "
        f"(threshold {thr:.2f}).{shares} Parameters from the set's refit, not from the single fits ranked below.",
        "",
        "| member | kind | adds shrink held-out | adds dLL held-out | parameters |",
        "|---|---|---|---|---|",
    ]
    long = []
    for m in members:
        if len(m["parameters"]) > TABLE_PARAMETERS:
            long.append(m)
        adds = m.get("adds_shrink")
        lines.append(
            f"| {m['effect']} | {m['kind']} | {'not measurable' if adds is None else f'{adds:.2f}'} | "
            f"{m['adds_dll_heldout']:+.1f} | {_parameters_cell(m['parameters'])} |"
        )
    for m in long:
        lines += _every_parameter_lines(f"{m['effect']} in the set", m["parameters"])
    n = sum(len(m["parameters"]) for m in members)
    n_not = sum(not_identified_count(m["parameters"]) for m in members)
    if n_not:
        lines += [
            "",
            f"{n_not} of the set's {n} parameters are not identified (their 1-sigma beyond the candidate's "
            "physical bound, or not identifiable from this log): the data do not narrow them, and no value "
            "is shown.",
        ]
    lines += _bound_note(sum(sum(at_bound(v) for v in m["parameters"].values()) for m in members), f"the set's {n}")
    return lines + [""]


def _bound_note(n_bound: int, of: str) -> list:
    """What a parameter held at a physical bound is (answers.at_bound), when
    any is."""
    if not n_bound:
        return []
    return [
        "",
        f"{n_bound} of {of} parameters {'is' if n_bound == 1 else 'are'} held at a physical bound (a thrust "
        "loss at 0): the data push against the bound, so the value is the bound, with no sampling sigma, "
        f"never counted beyond 2 sigma; the other parameters' sigmas are computed with "
        f"{'it' if n_bound == 1 else 'them'} held there.",
    ]


def _ranking_lines(result: dict) -> list:
    """The ranking table and the screening line."""
    lines = [
        "## Ranking (confirmed by full-filter refit on training blocks)",
        "",
        "| effect | kind | ln Bayes factor | BIC | dLL train | dLL held-out | shrink held-out [95 % CI] | explains | parameters |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    long = []
    for r in result["attribution"]:
        sh = r["shrink_heldout"]
        pars = _parameters_cell(r["parameters"])
        if len(r["parameters"]) > TABLE_PARAMETERS:
            long.append(r)
        lines.append(
            f"| {r['effect']} | {r['kind']} | {r['evidence']['ln_bf']:.1f} | {r['evidence']['bic']:.1f} | {r['evidence']['dll_train']:.1f} | "
            f"{r['evidence']['dll_heldout']:.1f} | {_shrink_cell(sh)} | "
            f"{'yes' if r['explains_heldout'] else 'no'} | {pars} |"
        )
    for r in long:
        lines += _every_parameter_lines(r["effect"], r["parameters"])
    n_bound = sum(sum(at_bound(v) for v in r["parameters"].values()) for r in result["attribution"])
    lines += _bound_note(n_bound, "the ranked candidates'")
    lines += [
        "",
        "Screening (linearised GLR, every candidate, -log10 p against chi-square(rank)): "
        + ", ".join(f"{s['effect']} {s['screen_logp']:.1f}" for s in result["screening"]),
        "",
    ]
    return lines


def _gap_map_lines(loc: dict) -> list:
    """The gap map and its top cells."""
    lines = [
        "## Gap map",
        "",
        "![gap map](gap_map.png)",
        "",
        "How to read the gyro rows: their regime columns (coasting, firing, slewing) test the raw "
        "sample-to-sample differences, where a torque error shows in the interval it is made; the "
        "'all' columns test the whitened rows, which add every earlier interval's error to each row. "
        "A torque error too small per interval to stand out of the gyro's noise in the firing rows "
        "alone can be large in 'all': the answer's 'acts mostly while' comes from the effect's own "
        "signature, per row, not from these columns.",
        "",
        "Top cells (family-wise p-values against the null's largest |z|):",
        "",
    ]
    for c in loc["top_cells"]:
        lines.append(
            f"- {c['stream']} {c['axis']} {c['regime']} {c['stat']}: z = {c['z']:.2f}"
            + (f", p {'<=' if c.get('p_beyond_null') else '='} {c['p_familywise']:.3f}" if "p_familywise" in c else "")
        )
    return lines


def _residual_lines(series: list, named: str, what: str) -> list:
    """The residual plot and the held-out RMS before and after."""
    lines = [
        "",
        "## Residuals and spectra, before and after",
        "",
        f"Shown: {what}.",
        "",
        "![residuals](residuals.png)",
        "",
    ]
    rms = [
        (
            nm,
            float(np.sqrt(np.nanmean(b[h] ** 2))) if np.any(h) else float("nan"),
            float(np.sqrt(np.nanmean(a[h] ** 2))) if a is not None and np.any(h) else None,
        )
        for nm, _, b, a, h, _ in series
    ]
    lines.append(
        "RMS on held-out rows, nominal"
        + (f" -> with {named}" if named else "")
        + ": "
        + ", ".join(f"{nm} {b:.3g}" + (f" -> {a:.3g}" if a is not None else "") for nm, b, a in rms)
    )
    return lines


def write_report(result: dict, out_dir, log_name: str = "log") -> Path:
    """Write the diagnosis as a markdown report with its gap map and residual
    plots into ``out_dir``; returns the report's path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    it = result["_internal"]
    save(gap_map_figure(it["cells"], result["statistics"]["map_threshold"]), out / "gap_map.png")
    best = result["attribution"][0] if result["attribution"] else None
    series, what = residual_series(result)
    named = " + ".join(m["effect"] for m in result.get("effects") or []) if result["verdict"] != "unexplained" else ""
    origin = float(result["log"].get("time_origin_s") or 0.0)
    save(residuals_figure(series, named, what, origin), out / "residuals.png", dpi=100)

    st = result["statistics"]
    loc = result["location"]
    lines = [f"# Gap diagnosis: {log_name}", ""]
    lines += ["## The three answers", ""]
    from bench.gap.answers import answer_lines

    for label, text in answer_lines(result):
        lines.append(f"- **{label.capitalize()}**: {text}" if label else f"  {text}")
    if not result["gap_detected"]:
        lines.append(f"- No gap at the calibrated false-alarm rate ({st['false_alarm_rate']}).")
    lines += [
        "",
        f"Detection: gap-map max |z| = {st['map_max_abs_z']:.2f} (threshold {st['map_threshold']:.2f}); "
        f"best screening -log10 p = {st['screen_logp_max']:.2f} (threshold {st['screen_logp_threshold']:.2f}); "
        f"thresholds from {st['calibration_runs']} null runs, false-alarm rate {st['false_alarm_rate']}.",
        "",
    ]
    lines += _not_told_apart_lines(result, best)
    lines += _set_lines(result)
    lines += _ranking_lines(result)
    lines += _gap_map_lines(loc)
    lines += _residual_lines(series, named, what)
    lines += [
        "",
        f"In the library but without a candidate model yet: {', '.join(result['not_modelled'])}.",
        "",
        f"Log: {result['log']['duration_s']:.0f} s, {result['log']['pose_updates']} pose updates "
        f"({result['log']['train_updates']} train / {result['log']['heldout_updates']} held out); "
        f"diagnosed in {result['elapsed_s']:.1f} s."
        + (f" Times are from {origin:.0f} s (the log's first IMU second)." if origin else ""),
    ]
    p = out / "README.md"
    p.write_text("\n".join(lines) + "\n")
    return p


def _shrink_cell(sh: dict) -> str:
    """The held-out shrink with its interval, or why there is none."""
    if not sh.get("measurable", True):
        return "not measurable"
    return f"{sh['fraction']:.2f} [{sh['ci95'][0]:.2f}, {sh['ci95'][1]:.2f}]"
