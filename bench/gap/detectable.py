"""Minimum detectable size of an effect for one run's manoeuvres.

Baarda's minimal detectable bias, for the diagnoser's own detection test.
The screening statistic of a candidate with k free directions is
2 dLL = |e0|^2 - min |e0 + J theta|^2 over the training rows; with the
effect present it is noncentral chi-square with k degrees of freedom and
noncentrality lambda = |P_J s|^2, where s is the effect's whitened signature
on those rows and P_J the projection onto the candidate's Jacobian. The
screen flags the effect when 2 dLL is beyond the chi2_k quantile of the
null-calibrated p-value threshold p* (bench/gap/null.py). The minimum
detectable size is the size at which that happens with probability POWER:

    P(chi2_k(lambda(size)) > c),  c = chi2_k.isf(p*),  equals POWER.

The signature comes from simulation with common random numbers: the run's
seed with the effect at a probe size, minus the same seed without it, both
whitened by the nominal model (the same replay the diagnoser runs). The
probes replay the effect-free run's valve commands open loop: closed loop,
a tiny effect flips a firing decision and the runs part ways, and that
divergence, not the effect, would fill the difference. lambda
grows as size^2 for a small effect; two more probes, each placed by the
power law through the two probes nearest the target, absorb the
nonlinearity. An effect without a candidate (out of the
library) uses its whole signature energy and k = its parameter count.

The size is per run, per drawn direction: a docking run that holds attitude
shows no gyro scale factor, and the same size is easy to see in a run that
slews. Sizes beyond the effect's largest sensible size are reported as
not detectable in that run. A probe that changes the run's length (the
chained approaches split elsewhere, no common rows to compare) is retried at
a quarter of its size.
"""
from __future__ import annotations

import numpy as np

POWER = 0.95
N_PROBES = 4
MAX_SHRINKS = 4


def required_noncentrality(k: int, c: float, power: float = POWER) -> float:
    """lambda with P(chi2_k(lambda) > c) = power."""
    from scipy.optimize import brentq
    from scipy.stats import chi2, ncx2

    if chi2.sf(c, k) >= power:
        return 0.0
    f = lambda lam: ncx2.sf(c, k, lam) - power  # noqa: E731
    hi = 10.0
    while f(hi) < 0.0:
        hi *= 2.0
    return float(brentq(f, 1e-9, hi, xtol=1e-6))


def _residuals(log, ctx_ref=None):
    """Whitened training residuals of the nominal model over ``log``, on the
    rows of ``ctx_ref`` (the effect-free run) when given."""
    from bench.gap.attribute import training_residuals
    from bench.gap.diagnose import context
    from bench.gap.replay import prepare

    ctx = context(prepare(log))
    if ctx_ref is None:
        e, rows_ok = training_residuals(ctx)
        return ctx, e, rows_ok
    if ctx.nominal.white.shape != ctx_ref.nominal.white.shape or (
            ctx.ch is not None and ctx.ch.e0.shape != ctx_ref.ch.e0.shape):
        raise ValueError("effect run and effect-free run differ in their streams' lengths")
    w = ctx.nominal.white[ctx_ref.train_nav]
    parts = [np.nan_to_num(w, nan=0.0)]
    e_dyn = ctx.ch.e0[ctx_ref.train_dyn].ravel() if ctx.ch is not None else np.zeros(0)
    return ctx, parts[0], e_dyn


def _cells(ctx) -> dict:
    """The gap map of the nominal pass over ctx's log: {(stream, axis, regime, stat): z}."""
    from bench.gap import localise
    from bench.gap.diagnose import _map_of

    cells = _map_of(ctx.d, ctx.nominal) + localise.dyn_cells(ctx.d, ctx.ch)
    return {(c["stream"], c["axis"], c["regime"], c["stat"]): c["z"] for c in cells}


def _next_size(probes: list, lam_req: float) -> float:
    """The size where lambda reaches lam_req: lambda ~ size^2 from one probe;
    from two, the power law through the two probes nearest lam_req (a
    nonlinear effect, or one whose small-size lambda is mostly noise)."""
    good = [p for p in probes if p["lambda"] and p["lambda"] > 0.0]
    last = good[-1]
    if len(good) >= 2:
        a, b = sorted(good, key=lambda p: abs(np.log(p["lambda"] / lam_req)))[:2]
        if a["size"] != b["size"] and a["lambda"] != b["lambda"]:
            slope = np.log(b["lambda"] / a["lambda"]) / np.log(b["size"] / a["size"])
            if 0.5 <= slope <= 8.0:
                return float(a["size"] * (lam_req / a["lambda"]) ** (1.0 / slope))
    return float(last["size"] * np.sqrt(lam_req / last["lambda"]))


def min_detectable_size(seed: int, name: str, unit_params, duration_s: float, calibration: dict,
                        simulate=None, power: float = POWER) -> dict:
    """The size of effect ``name`` along ``unit_params`` (a draw at size 1)
    that the diagnoser's screen detects with probability ``power`` in the
    run of ``seed``. Returns the size and how it was found."""
    from bench.effects import EFFECTS
    from bench.gap.attribute import numerical_rank, signature
    from bench.gap.candidates import CANDIDATES

    if simulate is None:
        from bench.effects import EffectSet
        from bench.reality import _clock_rate, log_config, runs_to_log, simulate_runs

        scripts = []

        def simulate(eff):
            # The effect-free run closed loop; each probe replays its valves open
            # loop, so the difference is the effect's physics and nothing the
            # controller did about it.
            runs = simulate_runs(seed, eff, duration_s, scripts=scripts if eff else None)
            if not eff:
                scripts[:] = [r["config"] for r in runs]
            return runs_to_log(runs, log_config(seed, duration_s), _clock_rate(EffectSet(eff)), with_truth=False)

    spec = EFFECTS[name]
    thr = float(calibration.get("thresholds", {}).get("screen_logp", np.nan))
    if not np.isfinite(thr):
        raise ValueError("the null calibration has no screen_logp threshold (regenerate it: python -m bench.gap.null)")
    ctx0, e0, rows_ok = _residuals(simulate({}))
    n = e0.size
    P = None
    k = spec.n_params
    if spec.in_library and name in CANDIDATES:
        J, _ = signature(ctx0, name, rows_ok)
        k = max(numerical_rank(J), 1)
        U, sv, _ = np.linalg.svd(J, full_matrices=False)
        U = U[:, sv > sv[0] * 1e-9] if sv.size and sv[0] > 0 else U[:, :0]
        P = U
    from scipy.stats import chi2, norm

    by_map = P is None
    if by_map:
        # No candidate: the gap map is the test. A cell's z moves by dz with the
        # effect (about N(dz, 1)): detected with `power` when the largest |dz|
        # reaches the map threshold plus the normal quantile of the power.
        thr_map = float(calibration["thresholds"]["map_max_abs_z"])
        z0 = _cells(ctx0)
        c = thr_map
        lam_req = float((thr_map + norm.isf(1.0 - power)) ** 2)
    else:
        c = float(chi2.isf(10.0 ** -thr, k))
        lam_req = required_noncentrality(k, c, power)
    size = float(spec.min_detectable)
    probes = []
    shrinks = 0
    while len(probes) < N_PROBES + shrinks:
        try:
            ctx1, w, e_dyn = _residuals(simulate({name: spec.at(unit_params, size).tolist()}), ctx0)
        except ValueError:
            # The effect changed the run's length (the chained approaches split at
            # other times): no common rows to compare. Probe smaller.
            probes.append({"size": size, "lambda": None, "note": "run length changed"})
            shrinks += 1
            if shrinks > MAX_SHRINKS:
                size = float("inf")
                break
            size *= 0.25
            continue
        e1 = np.concatenate([w[rows_ok].ravel(), e_dyn])
        s = e1 - e0
        if by_map:
            z1 = _cells(ctx1)
            lam = float(max((abs(z1[key] - z0[key]) for key in z0.keys() & z1.keys()), default=0.0) ** 2)
        else:
            lam = float(np.sum((P.T @ s) ** 2))
        probes.append({"size": size, "lambda": lam})
        if not lam > 0.0:
            size = float(spec.max_size)
            break
        size = _next_size(probes, lam_req)
        if size > spec.max_size:
            break
    detectable = bool(size <= spec.max_size)
    return {"effect": name, "size": size if detectable else float("nan"), "detectable": detectable,
            "test": "gap map" if by_map else "screen", "k": int(k), "threshold_2dll": float(c), "lambda_required": lam_req, "n_obs": int(n),
            "power": power, "probes": probes}
