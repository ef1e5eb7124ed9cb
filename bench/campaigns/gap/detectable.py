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

The signature comes from simulation with common random numbers, on the
manoeuvres the run really flies with the effect: each probe simulates the
run closed loop with the effect at the probe size (the run the campaign
will fly at that size), then replays its valve commands open loop without
the effect; the difference of the two, whitened by the nominal model (the
same replay the diagnoser runs), is the effect's signature on those
manoeuvres. (Probing on the effect-free run's manoeuvres instead misjudged
the size: a 1 % thrust loss changes which valves the controller fires, and
the noncentrality on the run actually flown was 0.25 to 2 times the
effect-free run's.) lambda grows about as size^2, scattered by the
manoeuvres changing with the size; the next probe is placed by the power
law through the two probes nearest the target. The answer is the smallest
probed size whose own run reaches the required noncentrality, so the run
flown at 1x has at least the stated power. An effect without a candidate
(out of the library) is tested by the gap map.

The size is per run, per drawn direction: a docking run that holds attitude
shows no gyro scale factor, and the same size is easy to see in a run that
slews. Sizes beyond the effect's largest sensible size are reported as
not detectable in that run. A probe that changes the run's length (the
chained approaches split elsewhere, no common rows to compare) is retried at
a quarter of its size.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

POWER = 0.95
MIN_PROBES = 2
MAX_PROBES = 6
SETTLE = 1.3  # a probe within this factor above the required noncentrality ends the search
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


def residuals_of(log, ctx_ref=None):
    """Whitened training residuals of the nominal model over ``log``, on the
    rows of ``ctx_ref`` (the effect-free run) when given."""
    from bench.gap.attribute import training_residuals
    from bench.gap.detection import context
    from bench.gap.load import prepare

    ctx = context(prepare(log))
    if ctx_ref is None:
        e, rows_ok = training_residuals(ctx)
        return ctx, e, rows_ok
    if ctx.nominal.white.shape != ctx_ref.nominal.white.shape or (
        ctx.ch is not None and ctx.ch.e0.shape != ctx_ref.ch.e0.shape
    ):
        raise ValueError("effect run and effect-free run differ in their streams' lengths")
    w = ctx.nominal.white[ctx_ref.train_nav]
    parts = [np.nan_to_num(w, nan=0.0)]
    e_dyn = ctx.ch.e0[ctx_ref.train_dyn].ravel() if ctx.ch is not None else np.zeros(0)
    return ctx, parts[0], e_dyn


def _cells(ctx) -> dict:
    """The gap map of the nominal pass over ctx's log: {(stream, axis, regime, stat): z}."""
    from bench.gap import localise
    from bench.gap.detection import map_cells

    cells = map_cells(ctx.d, ctx.nominal) + localise.dyn_cells(ctx.d, ctx.ch)
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


def _bench_simulate(seed: int, duration_s: float, then_scripts: list | None):
    """simulate(effects, scripts) -> (log, scripts) on the bench's docking runs."""
    from bench.sim.effects import EffectSet
    from bench.sim.reality import clock_rate, log_config, runs_to_log, simulate_runs

    def simulate(eff, scripts=None):
        runs = simulate_runs(seed, eff, duration_s, scripts=scripts, then_scripts=then_scripts)
        log = runs_to_log(runs, log_config(seed, duration_s), clock_rate(EffectSet(eff)), with_truth=False)
        return log, [r.config for r in runs]

    return simulate


def _probe(
    simulate,
    name: str,
    params: list,
    size: float,
    with_candidate: bool,
    thr_logp: float,
    thr_map: float,
    power: float,
    k_all: int,
) -> dict:
    """The noncentrality the effect at ``params`` gives the diagnoser's test
    in this run, and the noncentrality the test needs for ``power``."""
    from scipy.stats import chi2, norm

    from bench.gap.attribute import numerical_rank, signature

    # The run with the effect, closed loop: the manoeuvres the campaign's
    # run at this size will fly. Its valves replayed open loop without the
    # effect give the same manoeuvres' effect-free residuals, so the
    # difference is the effect's physics on those manoeuvres.
    log1, scripts = simulate({name: params})
    log0, _ = simulate({}, scripts)
    ctx0, e0, rows_ok = residuals_of(log0)
    ctx1, w, e_dyn = residuals_of(log1, ctx0)
    s = np.concatenate([w[rows_ok].ravel(), e_dyn]) - e0
    if with_candidate:
        J = signature(ctx0, name, rows_ok)[0]
        k = max(numerical_rank(J), 1)
        U, sv, _ = np.linalg.svd(J, full_matrices=False)
        U = U[:, sv > sv[0] * 1e-9] if sv.size and sv[0] > 0 else U[:, :0]
        lam = float(np.sum((U.T @ s) ** 2))
        c = float(chi2.isf(10.0**-thr_logp, k))
        lam_req = required_noncentrality(k, c, power)
    else:
        # No candidate: the gap map is the test. A cell's z moves by dz with the
        # effect (about N(dz, 1)): detected with `power` when the largest |dz|
        # reaches the map threshold plus the normal quantile of the power.
        z0, z1 = _cells(ctx0), _cells(ctx1)
        lam = float(max((abs(z1[key] - z0[key]) for key in z0.keys() & z1.keys()), default=0.0) ** 2)
        k, c = k_all, thr_map
        lam_req = float((thr_map + norm.isf(1.0 - power)) ** 2)
    return {
        "size": float(size),
        "lambda": lam,
        "lambda_required": lam_req,
        "k": int(k),
        "threshold": c,
        "n_obs": int(e0.size),
    }


def _search(probe, spec) -> tuple:
    """(answer, probes): probe sizes until the noncentrality's trend in size
    settles on the required one, up to the effect's largest sensible size."""
    size = float(spec.min_detectable)
    probes = []
    shrinks = 0
    while len(probes) < MAX_PROBES + shrinks:
        try:
            p = probe(size)
        except ValueError:
            # The effect changed the run's length (no common rows to compare). Probe smaller.
            probes.append({"size": size, "lambda": None, "note": "run length changed"})
            shrinks += 1
            if shrinks > MAX_SHRINKS:
                break
            size *= 0.25
            continue
        probes.append(p)
        if not p["lambda"] > 0.0:
            break
        if _settled(probes):
            break
        size = _next_size(probes, p["lambda_required"])
        if size > spec.max_size:
            # One look at the largest sensible size before calling it beyond the limit.
            if any(q.get("size") == spec.max_size for q in probes):
                break
            size = float(spec.max_size)
    answer = _answer(probes, spec.max_size)
    # The closed-loop runs' noncentrality scatters about its trend in size (the
    # manoeuvres change with the effect); if no probe reached the requirement
    # below the largest sensible size, step up from the largest probe.
    tries = 0
    while answer is None and tries < 3 and any(q.get("lambda") for q in probes):
        top = max(q["size"] for q in probes if q.get("lambda") is not None)
        if top >= spec.max_size:
            break
        try:
            probes.append(probe(min(1.5 * top, float(spec.max_size))))
        except ValueError:
            break
        tries += 1
        answer = _answer(probes, spec.max_size)
    return answer, probes


def min_detectable_size(
    seed: int,
    name: str,
    unit_params,
    duration_s: float,
    calibration: dict,
    simulate=None,
    power: float = POWER,
    then_scripts: list | None = None,
    max_size: float | None = None,
) -> dict:
    """The size of effect ``name`` along ``unit_params`` (a draw at size 1)
    that the diagnoser's screen detects with probability ``power`` in the
    run of ``seed`` with the effect at that size. Returns the size and how it
    was found.

    ``simulate(effects, scripts)`` returns (log, scripts): the run closed loop
    (scripts None) or replaying ``scripts`` open loop; ``then_scripts``: a
    characterisation flown after the docking runs (bench.sim.reality.simulate_runs);
    ``max_size``: the largest sensible size on the vehicle flown (default the
    effect library's, bench.sim.effects.max_size_for)."""
    from bench.gap.candidates import CANDIDATES
    from bench.sim.effects import EFFECTS

    if simulate is None:
        simulate = _bench_simulate(seed, duration_s, then_scripts)
    spec = EFFECTS[name]
    if max_size is not None:
        spec = replace(spec, max_size=float(max_size))
    thr = float(calibration.get("thresholds", {}).get("screen_logp", np.nan))
    if not np.isfinite(thr):
        raise ValueError(
            "the null calibration has no screen_logp threshold (regenerate it: python -m bench.commands.null_calibration)"
        )
    with_candidate = spec.in_library and name in CANDIDATES
    thr_map = float(calibration["thresholds"]["map_max_abs_z"])
    k_all = spec.n_params

    def probe(size: float) -> dict:
        return _probe(
            simulate, name, spec.at(unit_params, size).tolist(), size, with_candidate, thr, thr_map, power, k_all
        )

    answer, probes = _search(probe, spec)
    last = next((q for q in reversed(probes) if q.get("lambda") is not None), {})
    return {
        "effect": name,
        "size": answer["size"] if answer else float("nan"),
        "detectable": answer is not None,
        "test": "screen" if with_candidate else "gap map",
        "k": int(last.get("k", k_all)),
        "threshold_2dll": float(last.get("threshold", np.nan)),
        "lambda_required": float(last.get("lambda_required", np.nan)),
        "lambda_at_size": float(answer["lambda"]) if answer else float("nan"),
        "n_obs": int(last.get("n_obs", 0)),
        "power": power,
        "probes": probes,
    }


def _settled(probes: list) -> bool:
    """A probe at or above the required noncentrality by at most SETTLE (and
    at least MIN_PROBES probes): its size is the answer."""
    good = [p for p in probes if p.get("lambda") is not None]
    return len(good) >= MIN_PROBES and any(1.0 <= p["lambda"] / p["lambda_required"] <= SETTLE for p in good)


def _answer(probes: list, max_size: float) -> dict | None:
    """The smallest probed size whose run reaches the required noncentrality
    (that run is the one the campaign flies at 1x, so its power is known);
    without one, None (beyond the largest sensible size)."""
    ok = [
        p
        for p in probes
        if p.get("lambda") is not None and p["lambda"] >= p["lambda_required"] and p["size"] <= max_size
    ]
    return min(ok, key=lambda p: p["size"]) if ok else None
