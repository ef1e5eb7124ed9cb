"""Can a run's data tell its effect apart from each candidate in the library?

For scoring the blind campaign (bench/campaigns/gap/validate.py), after the answer is
frozen: the effect's whitened signature s on the run actually flown (the
run with the effect minus its valve commands replayed open loop without it,
common random numbers; the same construction as bench/campaigns/gap/detectable.py),
and for every candidate c in the library the part of that signature c
cannot reproduce, with c's parameters free:

    delta2_c = |(I - P_c) P_true s|^2        (in-library: what the true model fits)
    delta2_c = |(I - P_c) s|^2               (out of the library: all of it)

P the projection onto a candidate's Jacobian on the training rows: its
closest fit inside the candidate's physical bounds (a thrust loss cannot be
negative; bench/gap/attribute.py bounded_fit). delta2
is the squared distance, in noise standard deviations, between the data the
true effect predicts and the nearest the competitor can predict. Telling
two hypotheses at that distance apart from one noisy run is right with
probability Phi(sqrt(delta2) / 2) at best (equal priors); 95 % needs
delta2 >= (2 z_0.95)^2 = 10.8. Below that the data cannot separate the two,
whatever the diagnoser does, and the manoeuvre that would separate them is
the candidate's ``separate_by``.
"""

from __future__ import annotations

import numpy as np

from bench.gap.attribute import DELTA2_95
from bench.gap.candidates import candidates_of


def separability(
    seed: int,
    name: str,
    effects: dict,
    duration_s: float,
    in_library: bool,
    scripts: list | None = None,
    then_scripts: list | None = None,
) -> dict:
    """delta2 of effect ``name`` (parameters ``effects``) in the run of
    ``seed`` against every library candidate; the closest competitor.
    ``scripts``: fly these valve scripts (bench.sim.reality.simulate_runs) instead
    of the closed-loop docking runs; ``then_scripts``: fly these after the
    docking runs (bench.sim.reality.simulate_runs)."""
    log0, log1 = twin_logs(seed, effects, duration_s, scripts, then_scripts)
    return separability_of_logs(log0, log1, name, in_library)


def twin_logs(
    seed: int, effects: dict, duration_s: float, scripts: list | None = None, then_scripts: list | None = None
) -> tuple:
    """(log without the effects, log with them): the run of ``seed`` flown
    with ``effects``, and its valve commands replayed open loop without them
    (common random numbers), so the two differ by the effects alone."""
    from bench.sim.effects import EffectSet
    from bench.sim.reality import clock_rate, log_config, runs_to_log, simulate_runs

    runs1 = simulate_runs(seed, effects, duration_s, scripts=scripts, then_scripts=then_scripts)
    runs0 = simulate_runs(seed, {}, duration_s, scripts=[r.config for r in runs1], then_scripts=then_scripts)
    log1 = runs_to_log(runs1, log_config(seed, duration_s), clock_rate(EffectSet(effects)), with_truth=False)
    log0 = runs_to_log(runs0, log_config(seed, duration_s), 1.0, with_truth=False)
    return log0, log1


def separability_of_logs(log0, log1, name: str, in_library: bool) -> dict:
    """delta2 of the effect that makes ``log1`` differ from ``log0`` (the same
    flight and noise without it) against every library candidate."""
    from bench.campaigns.gap.detectable import residuals_of
    from bench.gap.attribute import bounded_fit, candidate, signature

    ctx0, e0, rows_ok = residuals_of(log0)
    try:
        _, w, e_dyn = residuals_of(log1, ctx0)
    except ValueError:
        return {"delta2": {}, "closest": None, "delta2_min": float("nan"), "note": "run length changed"}
    s = np.concatenate([w[rows_ok].ravel(), e_dyn]) - e0
    cands = candidates_of(ctx0.d)
    jac = {c: signature(ctx0, c, rows_ok)[0] for c in cands}

    def fit(c, v):
        # The data's residual s is removed by the candidate's correction J theta,
        # so the candidate reproduces s as -J theta.
        return bounded_fit(-jac[c], v, candidate(ctx0.d, c).lower, candidate(ctx0.d, c).bound)

    if in_library and name in jac:
        s = fit(name, s)
    lam = float(s @ s)
    d2 = {}
    for c in jac:
        if c == name:
            continue
        r = s - fit(c, s)
        d2[c] = float(r @ r)
    closest = min(d2, key=d2.get) if d2 else None
    return {
        "lambda": lam,
        "delta2": d2,
        "closest": closest,
        "delta2_min": d2[closest] if closest else float("nan"),
        "separable": bool(closest is None or d2[closest] >= DELTA2_95),
    }


def _stacked_fit(jac: dict, d, names: list, v: np.ndarray) -> np.ndarray:
    """The part of ``v`` the names' candidates reproduce together (-J theta,
    every parameter inside its physical bounds)."""
    from bench.gap.attribute import bounded_fit, candidate

    lo = np.concatenate([np.full(jac[n].shape[1], candidate(d, n).lower) for n in names])
    hi = np.concatenate([np.full(jac[n].shape[1], candidate(d, n).bound) for n in names])
    return bounded_fit(np.hstack([-jac[n] for n in names]), v, lo, hi)


def set_separability_of_logs(log0, log1, true_in: list) -> dict:
    """Can the run's data tell its set of in-library effects ``true_in``
    apart from every set one step away: one member replaced by another
    candidate, or one member left out (its part reproduced by the others)?

    As for one effect: s the whitened signature of everything in ``log1``
    that ``log0`` lacks, P_true s what the true set fits jointly, and for
    each competing set A, delta2_A = |(I - P_A) P_true s|^2. A larger set
    always fits at least as well, so supersets are a question of parsimony
    (the selection's threshold), not of separability, and are not tried.

    The out-of-library part (in + out runs): |(I - P_lib) s|^2 with P_lib the
    whole library fitted jointly, the largest set the diagnosis could name;
    below DELTA2_95 no answer could show that part as a remainder."""
    from bench.campaigns.gap.detectable import residuals_of
    from bench.gap.attribute import signature

    ctx0, e0, rows_ok = residuals_of(log0)
    try:
        _, w, e_dyn = residuals_of(log1, ctx0)
    except ValueError:
        return {"delta2": {}, "closest": None, "delta2_min": float("nan"), "note": "run length changed"}
    s = np.concatenate([w[rows_ok].ravel(), e_dyn]) - e0
    d = ctx0.d
    jac = {c: signature(ctx0, c, rows_ok)[0] for c in candidates_of(d)}
    true_in = [n for n in true_in if n in jac]
    p_true = _stacked_fit(jac, d, true_in, s) if true_in else np.zeros_like(s)
    d2 = {}
    for m in true_in:
        rest = [n for n in true_in if n != m]
        if rest:
            r = p_true - _stacked_fit(jac, d, rest, p_true)
            d2[f"without {m}"] = float(r @ r)
        for c in jac:
            if c in true_in:
                continue
            r = p_true - _stacked_fit(jac, d, rest + [c], p_true)
            d2[f"{m} -> {c}"] = float(r @ r)
    closest = min(d2, key=d2.get) if d2 else None
    r_lib = s - _stacked_fit(jac, d, list(jac), s)
    out_part = float(r_lib @ r_lib)
    return {
        "lambda": float(p_true @ p_true),
        "delta2": d2,
        "closest": closest,
        "delta2_min": d2[closest] if closest else float("nan"),
        "separable": bool(closest is None or d2[closest] >= DELTA2_95),
        "beyond_library_delta2": out_part,
        "beyond_library_separable": bool(out_part >= DELTA2_95),
    }


def set_separability(
    seed: int, effects: dict, true_in: list, duration_s: float, then_scripts: list | None = None
) -> dict:
    """set_separability_of_logs on the run of ``seed`` with ``effects`` and
    the same flight without them (common random numbers)."""
    log0, log1 = twin_logs(seed, effects, duration_s, then_scripts=then_scripts)
    return set_separability_of_logs(log0, log1, true_in)
