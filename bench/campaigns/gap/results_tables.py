"""Markdown tables of a blind campaign (the full JSON `proxops validate-gap
--json OUT` writes, with its keys and answers), as the campaign records in
docs/results/ show them:

    python -m bench.campaigns.gap.results_tables OUT.json
"""

from __future__ import annotations

import argparse
import json
from collections import Counter

import numpy as np

TARGETS = {
    "false_alarm": 0.02,
    "top1_1x": 0.85,
    "top1_2x": 0.95,
    "unexplained": 0.90,
    "misattribution": 0.05,
    "shrink_true": 0.80,
    "shrink_wrong": 0.20,
}


def _pct(x) -> str:
    return "-" if x is None else f"{100 * x:.1f} %"


def _answer(a: dict) -> str:
    if not a["gap_detected"]:
        return "no_gap"
    return a["verdict"] if a["verdict"] in ("unexplained", "partly_explained") else a["top1"]


def _correct(k: dict, a: dict) -> bool:
    return bool(a["gap_detected"] and a["verdict"] in ("explained", "ambiguous") and a["top1"] == k["effect"])


def scores_table(res: dict) -> str:
    inl = res["in_library_by_scale"]
    sep = res.get("in_library_by_scale_separable", {})
    o = res.get("out_of_library", {})
    sh = res["shrink_heldout"]
    n_null = res["n_null"]
    fa = res["false_alarm_rate"]
    rows = [("false alarms on null runs", f"{round(fa * n_null)} / {n_null} = {_pct(fa)}", "<= 2 %")]
    for s, tgt in (("1x", "85 %"), ("2x", "95 %")):
        v = inl.get(s)
        if v:
            rows.append(
                (
                    f"in-library {s}: detection / top-1 (n = {v['n']})",
                    f"{_pct(v['detection'])} / **{_pct(v['top1'])}**",
                    f"top-1 >= {tgt}",
                )
            )
        w = sep.get(s)
        if w:
            rows.append(
                (
                    f"in-library {s}, runs whose data separate the effect from every other candidate: top-1 "
                    f"(n = {w['n_separable']}; {w['n_not_separable']} not separable)",
                    _pct(w["top1_separable"]),
                    "-",
                )
            )
    if o:
        rows.append(
            (
                f"out-of-library (n = {o['n']}): unexplained / not detected / confident misattribution",
                f"**{_pct(o['unexplained_rate'])}** / {_pct(o['not_detected_rate'])} / "
                f"**{_pct(o['confident_misattribution_rate'])}**",
                ">= 90 % / - / <= 5 %",
            )
        )
    rows.append(
        (
            f"held-out shrink, true effect fitted (median, n = {sh['n_true']})",
            f"**{sh['true_effect_median']:.2f}**" if sh["true_effect_median"] is not None else "-",
            ">= 0.80",
        )
    )
    rows.append(
        (
            f"held-out shrink, a wrong effect fitted (median, n = {sh['n_wrong']})",
            f"**{sh['wrong_effect_median']:.2f}**" if sh["wrong_effect_median"] is not None else "-",
            "<= 0.20",
        )
    )
    cov = res["interval_coverage_95"]
    rows.append(
        (
            f"95 % interval coverage of the true effect's fitted parameters ({cov['n_parameters']})",
            f"{cov['fraction']:.3f}" if cov["fraction"] is not None else "-",
            "-",
        )
    )
    t = res["timing_s"]
    what = f"{res.get('duration_s', 120.0):g} s of docking" + (
        " then the characterisation" if res.get("manoeuvres", "docking") != "docking" else ""
    )
    rows.append(
        (
            f"diagnosis time per run ({what}), median / max",
            f"{t['diagnose_median']:.2f} s / {t['diagnose_max']:.2f} s",
            "-",
        )
    )
    out = ["| score | result | target |", "|---|---|---|"]
    out += [f"| {a} | {b} | {c} |" for a, b, c in rows]
    return "\n".join(out)


def per_effect_table(res: dict) -> str:
    from bench.sim.effects import EFFECTS

    by = {a["run"]: a for a in res["answers"]}
    keys = [k for k in res["keys"] if k["category"] == "in_library"]
    out = [
        "| effect | runs (detectable) | 1x: detected / top-1 | 2x: detected / top-1 | min. detectable size, "
        "median [range] | not separable (closest candidate) | most frequent wrong answer |",
        "|---|---|---|---|---|---|---|",
    ]
    for name in sorted({k["effect"] for k in keys}):
        ks = [k for k in keys if k["effect"] == name]
        det = [k for k in ks if k.get("detectable", True)]
        cells = []
        for s in (1.0, 2.0):
            sel = [k for k in det if k["scale"] == s]
            cells.append(
                f"{sum(by[k['run']]['gap_detected'] for k in sel)}/{len(sel)} / "
                f"{sum(_correct(k, by[k['run']]) for k in sel)}/{len(sel)}"
            )
        md = [
            k["min_detectable"] for k in det if k.get("min_detectable") is not None and np.isfinite(k["min_detectable"])
        ]
        mds = f"{np.median(md):.3g} [{min(md):.3g}, {max(md):.3g}] {EFFECTS[name].unit}" if md else "-"
        ns = [
            by[k["run"]]["separability"]["closest"]
            for k in det
            if by[k["run"]].get("separability", {}).get("separable") is False
        ]
        nss = f"{len(ns)}" + (f" ({', '.join(f'{c} {n}' for c, n in Counter(ns).most_common())})" if ns else "")
        wrong = Counter(_answer(by[k["run"]]) for k in det if not _correct(k, by[k["run"]]))
        ww = ", ".join(f"{c} ({n})" for c, n in wrong.most_common(2)) or "-"
        out.append(f"| {name} | {len(ks)} ({len(det)}) | {cells[0]} | {cells[1]} | {mds} | {nss} | {ww} |")
    return "\n".join(out)


def out_of_library_table(res: dict) -> str:
    by = {a["run"]: a for a in res["answers"]}
    keys = [k for k in res["keys"] if k["category"] == "out_of_library"]
    out = [
        "| out-of-library effect | runs (detectable) | unexplained | not detected | explained (as) | ambiguous (as) "
        "| closest candidate, median delta2 |",
        "|---|---|---|---|---|---|---|",
    ]
    for name in sorted({k["effect"] for k in keys}):
        ks = [k for k in keys if k["effect"] == name]
        det = [k for k in ks if k.get("detectable", True)]
        ans = [by[k["run"]] for k in det]
        une = sum(a["gap_detected"] and a["verdict"] == "unexplained" for a in ans)
        nd = sum(not a["gap_detected"] for a in ans)
        ex = Counter(a["top1"] for a in ans if a["gap_detected"] and a["verdict"] == "explained")
        am = Counter(a["top1"] for a in ans if a["gap_detected"] and a["verdict"] == "ambiguous")
        sep = [a.get("separability", {}) for a in ans]
        close = Counter(s.get("closest") for s in sep if s.get("closest"))
        d2 = [s["delta2_min"] for s in sep if s.get("delta2_min") is not None and np.isfinite(s["delta2_min"])]
        cl = f"{close.most_common(1)[0][0]}, {np.median(d2):.1f}" if close and d2 else "-"
        fmt = lambda c: f"{sum(c.values())}" + (f" ({', '.join(f'{e} {n}' for e, n in c.most_common())})" if c else "")  # noqa: E731
        out.append(f"| {name} | {len(ks)} ({len(det)}) | {une} | {nd} | {fmt(ex)} | {fmt(am)} | {cl} |")
    return "\n".join(out)


def beyond_limit_table(res: dict) -> str:
    b = res["beyond_detection_limit"]["by_effect"]
    out = [
        "| beyond the detection limit of its run | runs | detected at the largest sensible size | answers |",
        "|---|---|---|---|",
    ]
    for name in sorted(b):
        v = b[name]
        out.append(
            f"| {name} | {v['n']} | {v['detected']} | "
            + ", ".join(f"{a} {n}" for a, n in sorted(v["answers"].items()))
            + " |"
        )
    return "\n".join(out)


def shrink_by_scale(res: dict) -> str:
    by = {a["run"]: a for a in res["answers"]}
    lines = []
    for s in (1.0, 2.0):
        for which in ("true_fit", "wrong_fit"):
            v = [
                by[k["run"]][which]["shrink"]
                for k in res["keys"]
                if k["category"] == "in_library"
                and k.get("detectable", True)
                and k["scale"] == s
                and which in by[k["run"]]
                and by[k["run"]][which].get("measurable")
            ]
            med = f"{np.median(v):.2f}" if v else "-"
            lines.append(f"- {s:g}x, {which.replace('_fit', '')} effect fitted: median {med} (n = {len(v)})")
    v = np.asarray([s for _, s in _true_shrinks(res)])
    if v.size:
        lo, hi = median_interval(v)
        lines.append(
            f"- both sizes, true effect fitted: median {np.median(v):.4f} (n = {v.size}), 95 % bootstrap "
            f"interval of the median [{lo:.2f}, {hi:.2f}] ({BOOTSTRAP_RESAMPLES} resamples of the runs)"
        )
    return "\n".join(lines)


BOOTSTRAP_RESAMPLES = 10000


def median_interval(v: np.ndarray, resamples: int = BOOTSTRAP_RESAMPLES, seed: int = 0) -> tuple:
    """95 % bootstrap interval of the median of ``v`` (runs resampled with
    replacement, seeded; scipy's percentile interval, the one the records
    quote)."""
    from scipy.stats import bootstrap

    v = np.asarray(v, float)
    if v.size == 1:  # every resample is that one run (scipy asks for two)
        return float(v[0]), float(v[0])
    ci = bootstrap(
        (v,),
        np.median,
        n_resamples=resamples,
        method="percentile",
        random_state=np.random.default_rng(seed),
    ).confidence_interval
    return float(ci.low), float(ci.high)


def _true_shrinks(res: dict) -> list:
    """(effect, shrink) of the true effect's forced fit on every measurable in-library run."""
    by = {a["run"]: a for a in res["answers"]}
    return [
        (k["effect"], by[k["run"]]["true_fit"]["shrink"])
        for k in res["keys"]
        if k["category"] == "in_library"
        and k.get("detectable", True)
        and by[k["run"]].get("true_fit", {}).get("measurable")
    ]


def shrink_by_effect(res: dict) -> str:
    per = {}
    for e, s in _true_shrinks(res):
        per.setdefault(e, []).append(s)
    rows = sorted(per.items(), key=lambda kv: -np.median(kv[1]))
    out = ["| effect | measurable runs | median shrink, true effect fitted |", "|---|---|---|"]
    out += [f"| {e} | {len(v)} | {np.median(v):.2f} |" for e, v in rows]
    return "\n".join(out)


def main(argv=None) -> int:
    from bench.report import restore_non_finite

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("json", help="the full JSON of proxops validate-gap --json (or .json.gz)")
    args = ap.parse_args(argv)
    if args.json.endswith(".gz"):
        import gzip

        res = restore_non_finite(json.loads(gzip.open(args.json, "rt").read()))
    else:
        res = restore_non_finite(json.loads(open(args.json).read()))
    if "keys" not in res or "answers" not in res:
        raise SystemExit(f"{args.json}: no 'keys'/'answers' (the summary, not the full JSON the command writes)")
    for title, body in (
        ("Scores against the issue's targets", scores_table(res)),
        ("Per in-library effect", per_effect_table(res)),
        ("Out-of-library effects", out_of_library_table(res)),
        ("Beyond the detection limit of their run", beyond_limit_table(res)),
        ("Held-out shrink by size (measurable runs)", shrink_by_scale(res)),
        ("Held-out shrink by effect (measurable runs)", shrink_by_effect(res)),
    ):
        print(f"### {title}\n\n{body}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
