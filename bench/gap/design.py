"""Design the test that separates: a short open-loop valve plan, for the
log's own described vehicle, that tells apart the sets of effects a
diagnosis could not (docs/GAP.md, "Designing the test that separates").

The hypotheses are sets of candidates at sizes fitted on the log: the
answer's set and the sets it cannot be told from (``ambiguous_with``), each
fitted jointly on the log's training rows inside its members' bounds; a set
listed as a hidden member beside another (``add``, ``to``) carries that
member at the share of the gap the listing gave it, in the direction the
log hides best, its other members refitted (as bench/gap/alternatives.py
builds it).

The plan is made of elementary blocks, each flown from rest as a run of its
own: the valves closed for LEAD_S (navigation initialises on the first
poses), one valve open for a pulse of PULSES_S, then a coast of COASTS_S.
The described vehicle flies every (valve, pulse) once, noise-free, on the
bench's plant (bench/sim/vehicle_sim.py) with the longest coast; a block
with a shorter coast is the start of that run (the replay and the whitening
are causal). Every member's whitened Jacobian on that log (the nominal
replay and the dynamics channel, every row) is split by block, and so is
each hypothesis's signature s_A,k: the same flight with its effects less
the flight without (exact where its linearisation J_A theta_A is not: a
nozzle tilted 0.25 rad). A plan is w_k >= 0 repetitions of block k, each
flown as a run of its own with its own noise, so its rows are block k's
scaled by sqrt(w_k). For hypothesis A at its sizes and a set B,

    d_AB(w) = min_{u in B's bounds} sum_k w_k |s_A,k - J_B,k u|^2

is the squared distance, in noise standard deviations, between what A
predicts and the nearest B can produce (bench/campaigns/gap/separability.py; 10.8 =
DELTA2_95 separates 95 % of the time). A direction counts unless B holds
every member of A (B then reproduces A exactly: the pair is separated when
the larger set's extra members show, the other direction). When B is A
with one member c more, B's sizes are the one direction of c the log hid
best; the effect may lie along any other, so the plan must also separate
c along each of its directions alone at B's size
(worst_case_directions): a plan made for B's sizes alone fired the one
valve that direction tilts most and missed a real tilt of two others.

d_AB is a minimum of functions linear in w, so it is concave: maximising
the smallest counting d_AB over w, subject to linear limits (duration,
delta-v), is a convex problem, solved by SLSQP on the epigraph form
(maximise t, t <= d_AB(w) for every counting direction) with the exact
gradient dd_AB/dw_k = |s_A,k - J_B,k u*|^2 (the envelope theorem at the
bounded fit u*); then rounded to whole repetitions (_round) and
re-evaluated. With a target distance instead, the shortest plan that
reaches it (same constraints, duration the objective).

The fixed plan: the characterisation, every valve alone for
CHARACTERISATION_FIRE_S then CHARACTERISATION_COAST_S after LEAD_S closed
(bench/sim/plans.py), one point of the same space (w = 1 on those blocks),
evaluated the same way.

Checked, not promised (flown_distances, check): the plan flown on the
bench's plant with a hypothesis's effects and without them, common random
numbers, and the distance measured on that flight.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from bench.gap.alternatives import HIDDEN_SHARE, hiding_fits
from bench.gap.attribute import DELTA2_95
from bench.sim.plans import CHARACTERISATION_COAST_S, CHARACTERISATION_FIRE_S, LEAD_S

CYCLE_S = 0.1  # one valve command per control cycle, the valve held open through the pulse
PULSES_S = (0.5, 1.0, 2.0, 3.0)
COASTS_S = (2.0, 5.0, 10.0, CHARACTERISATION_COAST_S)
START_R_HILL_M = (0.2, -1.5, 0.1)  # each run from rest here, body axes on the Hill axes
DEFAULT_MAX_DURATION_S = 120.0
DEFAULT_MIN_ON_TIME_S = 0.1
MAX_REPEATS = 50  # repetitions of one block
# The probability with which a designed plan should make each of the
# diagnosis's tests pass (selection_level), as DELTA2_95 separates a pair.
POWER = 0.95
CRITERIA = ("selection", "pairwise")
# Passes of the designed schedule. The diagnosis trains on alternate time
# blocks and scores on the others (quantify.excitation_split), so a firing
# flown once falls in one half only; two passes put every firing in both
# (bench/sim/plans.py's passes), each within half the limits. Flown once,
# a plan whose distance reached 131 was answered "unexplained"; in two
# passes its set was named (docs/GAP.md).
DEFAULT_PASSES = 2


@dataclass
class Hypothesis:
    """A set of candidates at the sizes fitted on the log."""

    members: list
    theta: dict  # {candidate: parameters, in the candidate's own units}
    how: str = "fitted jointly on the log's training rows"

    @property
    def name(self) -> str:
        return " + ".join(self.members) if self.members else "nothing in the library"


@dataclass
class Block:
    """Valve ``valve`` open for ``pulse_s`` after LEAD_S, then ``coast_s``; flown from rest."""

    valve: int
    pulse_s: float
    coast_s: float
    delta_v_mps: float

    @property
    def duration_s(self) -> float:
        return LEAD_S + self.pulse_s + self.coast_s


def shortest_block_s(min_on_time_s: float, passes: int = 1) -> float:
    """The shortest plan the limits allow: ``passes`` of the shortest block
    (its pulse at least the minimum on-time)."""
    pulses = [p for p in PULSES_S if p >= min_on_time_s] or [min_on_time_s]
    return passes * (LEAD_S + min(pulses) + min(COASTS_S))


# --- the hypotheses, fitted on the log ----------------------------------------------------------


def _log_problem(log):
    """(ctx, e0, rows_ok) of the log's nominal model on its training rows."""
    from bench.gap.attribute import training_residuals
    from bench.gap.detection import context
    from bench.gap.load import prepare

    ctx = context(prepare(log))
    e0, rows_ok = training_residuals(ctx)
    return ctx, e0, rows_ok


def _scaled(ctx, jac: dict, names: list) -> tuple:
    """(J, lo, hi, scales) of the names' stacked Jacobians in units of each candidate's scale."""
    from bench.gap.attribute import candidate

    cs = [candidate(ctx.d, n) for n in names]
    J = np.hstack([jac[n] * c.scale for n, c in zip(names, cs)]) if names else np.zeros((0, 0))
    lo = np.concatenate([np.full(jac[n].shape[1], c.lower / c.scale) for n, c in zip(names, cs)])
    hi = np.concatenate([np.full(jac[n].shape[1], c.bound / c.scale) for n, c in zip(names, cs)])
    sc = np.concatenate([np.full(jac[n].shape[1], c.scale) for n, c in zip(names, cs)])
    return J, lo, hi, sc


def _split(names: list, jac: dict, u: np.ndarray) -> dict:
    edges = np.cumsum([0] + [jac[n].shape[1] for n in names])
    return {n: u[a:b] for n, a, b in zip(names, edges[:-1], edges[1:])}


def _fit_set(ctx, jac: dict, names: list, target: np.ndarray) -> tuple:
    """(theta by name, in candidate units; the fitted signature J theta): the
    bounded least-squares fit of the names' stacked Jacobians to ``target``."""
    from bench.gap.select import bounded_lstsq

    if not names:  # the empty set reproduces nothing
        return {}, np.zeros_like(target)
    J, lo, hi, sc = _scaled(ctx, jac, names)
    u = bounded_lstsq(J, target, lo, hi)
    return _split(names, jac, u * sc), J @ u


def hidden_hypothesis(ctx, jac: dict, e0: np.ndarray, base: list, c: str, share: float | None = None) -> Hypothesis:
    """``base`` fitted on the log with candidate ``c`` beside it carrying
    ``share`` noise variances of signature on the log's training rows
    (default: HIDDEN_SHARE of the base's fitted signature, at least
    DELTA2_95), in the direction the base's members, refitted, absorb best:
    the set a listing "hidden member" stands for, at its sizes
    (alternatives.hiding_fits, the best of its directions)."""
    _, sig = _fit_set(ctx, jac, base, -e0)
    share = float(share) if share else max(DELTA2_95, HIDDEN_SHARE * float(sig @ sig))
    J, lo, hi, sc = _scaled(ctx, jac, base)
    Jc, lc, hc, scc = _scaled(ctx, jac, [c])
    best = min(hiding_fits(J, lo, hi, Jc, lc, hc, sig, share), key=lambda f: f[0], default=None)
    if best is None:  # no direction carries the share inside the bounds: fitted jointly instead
        theta, _ = _fit_set(ctx, jac, base + [c], -e0)
        return Hypothesis(base + [c], theta)
    d2, u, u_c = best
    theta = {**_split(base, jac, u * sc), c: u_c * scc}
    how = f"{c} carrying {share:.4g} noise variances of signature beside {' + '.join(base)} (log: distance {d2:.3g})"
    return Hypothesis(base + [c], theta, how)


def _names(value, field: str) -> list:
    """A list of effect names read back from a diagnosis file, or a one-line
    error naming the field."""
    if not isinstance(value, list) or not value or not all(isinstance(n, str) for n in value):
        raise ValueError(f"diagnosis {field}: {value!r} is not a list of effect names")
    if len(set(value)) != len(value):
        raise ValueError(f"diagnosis {field}: {value!r} names an effect twice")
    return list(value)


def sets_of_diagnosis(out: dict) -> list:
    """[(members, listing entry or None)]: the answer's set, then every set it
    cannot be told from (bench/gap/answers.py listed_sets). The diagnosis is
    a file read back (proxops diagnose --json): every field used is checked
    and a wrong one refused with its name; the effect names are checked
    against the log's candidates when the sets are fitted."""
    import math

    if not isinstance(out, dict):
        raise ValueError("the diagnosis is not a JSON object")
    effects = out.get("effects") or []
    if not isinstance(effects, list) or not all(isinstance(m, dict) for m in effects):
        raise ValueError("diagnosis effects: not a list of objects")
    answer = _names([m.get("effect") for m in effects], "effects[].effect") if effects else []
    if not answer:
        raise ValueError("the diagnosis names no effect: there is no answer to separate")
    entries = out.get("ambiguous_with") or []
    if not isinstance(entries, list) or not all(isinstance(a, dict) for a in entries):
        raise ValueError("diagnosis ambiguous_with: not a list of objects")
    sets = [(answer, None)]
    for i, a in enumerate(entries):
        field = f"ambiguous_with[{i}]"
        members = _names(a["set"] if "set" in a else [a.get("effect")], f"{field}.set")
        if "add" in a:
            to = _names(a.get("to"), f"{field}.to")
            if a["add"] not in members or sorted(to + [a["add"]]) != sorted(members):
                raise ValueError(f"diagnosis {field}: add {a['add']!r} beside {to} is not the set {members}")
            share = a.get("hidden_signature2")
            if share is not None and not (isinstance(share, (int, float)) and math.isfinite(share) and share > 0):
                raise ValueError(f"diagnosis {field}.hidden_signature2: {share!r} is not a positive number")
        sets.append((members, a))
    return sets


def fit_hypotheses(log, sets: list) -> list:
    """Every set [(members, listing entry or None)] at its sizes on ``log``:
    jointly fitted; a hidden member of a listing (``add`` beside ``to``), or
    a named set one member larger than another named set, carries its share
    (hidden_hypothesis)."""
    from bench.gap.attribute import signature
    from bench.gap.candidates import candidates_of

    ctx, e0, rows_ok = _log_problem(log)
    known = candidates_of(ctx.d)
    names = sorted({n for members, _ in sets for n in members})
    bad = [n for n in names if n not in known]
    if bad:
        raise ValueError(f"hypothesis {bad[0]!r}: not a candidate of this log (known: {', '.join(sorted(known))})")
    jac = {n: signature(ctx, n, rows_ok)[0] for n in names}
    out = []
    for members, entry in sets:
        if entry is not None and "add" in entry and "to" in entry:
            out.append(hidden_hypothesis(ctx, jac, e0, list(entry["to"]), entry["add"], entry.get("hidden_signature2")))
            continue
        theta, _ = _fit_set(ctx, jac, list(members), -e0)
        h = Hypothesis(list(members), theta)
        inner = [m for m, _ in sets if set(m) < set(members) and len(set(members) - set(m)) == 1]
        if entry is None and inner:
            # One member more than another named set: that member at least at
            # a share worth naming (the joint fit where the data give it more).
            base = inner[0]
            (c,) = set(members) - set(base)
            hidden = hidden_hypothesis(ctx, jac, e0, list(base), c)
            if float(np.sum((jac[c] @ theta[c]) ** 2)) < float(np.sum((jac[c] @ hidden.theta[c]) ** 2)):
                h = Hypothesis(hidden.members, hidden.theta, hidden.how)
        out.append(h)
    return out


# --- the blocks, flown by the described vehicle -------------------------------------------------


def description_of(log) -> dict:
    """The log's described vehicle, sensors and orbit as a full description
    (every default resolved, bench/sim/log_description.py), for flying plans."""
    from bench.gap.load import prepare

    d = prepare(log)
    r = d.desc
    return {
        "vehicle": {
            "mass_kg": float(r.mass_kg),
            "inertia_kgm2": np.asarray(r.inertia_kgm2, float).tolist(),
            "com_b_m": np.asarray(r.com_b_m, float).tolist(),
            "thrusters": [
                {
                    "position_b_m": np.asarray(t.position_b_m, float).tolist(),
                    "direction_b": np.asarray(t.direction_b, float).tolist(),
                    "thrust_n": float(t.thrust_n),
                    "min_on_time_s": float(t.min_on_time_s),
                }
                for t in r.thrusters
            ],
            "envelope_m": float(r.envelope_m),
        },
        "imu": {
            "rate_hz": float(r.imu_rate_hz or 1.0 / d.dt_s),
            "q_body_imu": np.asarray(r.imu_q_body_imu, float).tolist(),
            "position_b_m": np.asarray(r.imu_position_b_m, float).tolist(),
            "accel_sigma_mps2": float(r.accel_sigma_mps2),
            "gyro_sigma_rps": float(r.gyro_sigma_rps),
        },
        "pose_sensor": {
            "reference_point_b_m": np.asarray(r.pose_reference_b_m, float).tolist(),
            "time_offset_s": float(r.pose_time_offset_s),
            "latency_s": float(r.pose_latency_s),
        },
        "orbit": {"radius_m": float(r.orbit_radius_m)},
    }


def _thrusts(description: dict) -> tuple:
    from bench.sim.log_description import resolve

    r = resolve(description)
    return np.array([t.thrust_n for t in r.thrusters]), np.array([t.min_on_time_s for t in r.thrusters]), r.mass_kg


def catalogue(description: dict, min_on_time_s: float) -> list:
    """Every block the limits allow: each valve, each pulse at least the
    minimum on-time (the user's and the valve's own), each coast."""
    thrust, min_on, mass = _thrusts(description)
    out = []
    for i in range(thrust.size):
        for p in PULSES_S:
            if p < max(min_on_time_s, min_on[i]):
                continue
            out += [Block(i, p, c, float(thrust[i] * p / mass)) for c in COASTS_S]
    return out


def run_segment(valve: int, pulse_s: float, coast_s: float, n_valves: int, manoeuvre: str = "characterisation"):
    """One run of the bench's vehicle simulator: closed for LEAD_S, valve
    ``valve`` open for ``pulse_s`` (a command each control cycle), closed
    for ``coast_s``."""
    from bench.sim.vehicle_sim import PlanSegment

    n = int(round(pulse_s / CYCLE_S))
    on = np.zeros((n, n_valves))
    on[:, valve] = CYCLE_S
    return PlanSegment(
        manoeuvre,
        LEAD_S + pulse_s + coast_s,
        np.array(START_R_HILL_M, float),
        np.array([1.0, 0.0, 0.0, 0.0]),
        LEAD_S + CYCLE_S * np.arange(n),
        on,
    )


def all_rows(ctx):
    """The context with every finite row counted (not only the training blocks)."""
    ok = np.all(np.isfinite(ctx.nominal.white), axis=1)
    train_dyn = np.ones(ctx.ch.rows, bool) if ctx.ch is not None else None
    return dataclasses.replace(ctx, train_nav=ok, train_dyn=train_dyn)


def row_times(ctx) -> np.ndarray:
    """The time of every row of a Jacobian on all_rows(ctx): the pose updates (6 each), then the dynamics rows (3)."""
    t_nav = np.repeat(ctx.d.pose_tc[ctx.train_nav], 6)
    t_dyn = np.repeat(ctx.ch.t, 3) if ctx.ch is not None else np.zeros(0)
    return np.concatenate([t_nav, t_dyn])


def _segment_starts(d) -> np.ndarray:
    return np.array([d.imu_t[d.imu_seg == s][0] - d.dt_s for s in np.unique(d.imu_seg)])


def simulable(h: Hypothesis) -> bool:
    """Whether the bench's vehicle simulator flies every member of ``h`` (not a drifting clock)."""
    from bench.sim.vehicle_sim import KNOWN

    return all(n in KNOWN for n in h.members)


def effects_of(h: Hypothesis) -> dict:
    """The hypothesis as the simulator's effects (the candidates' parameters are the effects')."""
    return {n: np.asarray(v, float).ravel().tolist() for n, v in h.theta.items()}


def whitened_rows(ctx, ok: np.ndarray) -> np.ndarray:
    """Every row of a log's nominal model (the pose updates ``ok``, then the dynamics channel), whitened."""
    return np.concatenate([np.nan_to_num(ctx.nominal.white[ok], nan=0.0).ravel(), ctx.ch.e0.ravel()])


def block_jacobians(description: dict, blocks: list, hyps: list) -> tuple:
    """({name: [J of block k]}, {hypothesis index: [its signature on block
    k]}, rows per block, the flight's LogData): every member's whitened
    Jacobian on each block's rows, from one noise-free flight of every
    (valve, pulse) with the longest coast; and each hypothesis's exact
    signature there, the same flight with its effects less the flight
    without (sign as J theta: what its correction removes), where the
    simulator flies all its members at their fitted sizes (else its
    linear signature, J theta, is used downstream)."""
    from bench.gap.attribute import signature
    from bench.gap.detection import context
    from bench.gap.load import prepare
    from bench.sim.vehicle_sim import simulate

    n_valves = _thrusts(description)[0].size
    runs = sorted({(b.valve, b.pulse_s) for b in blocks})
    coast = max(COASTS_S)
    plan = [run_segment(v, p, coast, n_valves) for v, p in runs]
    log, _ = simulate(description, plan, {}, seed=0, with_truth=False, noise_scale=0.0)
    ctx = all_rows(context(prepare(log)))
    ok = ctx.train_nav
    t = row_times(ctx)
    starts = _segment_starts(ctx.d)
    seg = np.searchsorted(starts, t, side="right") - 1
    since = t - starts[seg]
    names = sorted({n for h in hyps for n in h.members})
    jac = {n: signature(ctx, n, ok[ok])[0] for n in names}
    masks = []
    for b in blocks:
        r = runs.index((b.valve, b.pulse_s))
        masks.append((seg == r) & (since <= b.duration_s + 1e-9))
    e0 = whitened_rows(ctx, ok)
    sig = {}
    for i, h in enumerate(hyps):
        if not simulable(h) or not h.members:
            continue
        try:
            log_h, _ = simulate(description, plan, effects_of(h), seed=0, with_truth=False, noise_scale=0.0)
        except ValueError:
            # Fitted sizes the simulator refuses to fly (a differential drag
            # whose host ballistic coefficient came out negative): the fit
            # is a direction in the log's rows, so the linear signature.
            continue
        ctx_h = context(prepare(log_h))
        if ctx_h.nominal.white.shape != ctx.nominal.white.shape or ctx_h.ch.e0.shape != ctx.ch.e0.shape:
            continue  # the streams changed length: the linear signature instead
        s = e0 - whitened_rows(ctx_h, ok)
        sig[i] = [s[m] for m in masks]
    return {n: [J[m] for m in masks] for n, J in jac.items()}, sig, [int(m.sum()) for m in masks], ctx.d


# --- the distances and the design ---------------------------------------------------------------


@dataclass
class Direction:
    """Hypothesis ``a`` at its sizes against set ``b`` (free inside its bounds), per block."""

    a: int
    b: int
    s2: np.ndarray  # (n_blocks,) |J_A,k theta_A|^2
    h: np.ndarray  # (n_blocks, p) J_B,k^T J_A,k theta_A (scaled units)
    G: np.ndarray  # (n_blocks, p, p) J_B,k^T J_B,k
    lo: np.ndarray
    hi: np.ndarray
    # A member of a family (worst_case_directions): {"member", "parameter", "theta"}.
    family: dict | None = None
    # The distance this direction must reach (selection_levels), and which
    # test of the diagnosis asks it: distance() is in units of it.
    required: float = 1.0
    test: str = "pair"
    b_name: str | None = None  # set B when it is none of the hypotheses (a member test's A less one member)

    def distance(self, w: np.ndarray) -> tuple:
        """(d_AB(w), its gradient in w, u*), d and its gradient in units of ``required``."""
        from scipy.optimize import lsq_linear

        G = np.tensordot(w, self.G, 1)
        h = w @ self.h
        c = float(w @ self.s2)
        lam, V = np.linalg.eigh(G)
        keep = lam > max(lam.max(initial=0.0), 0.0) * 1e-12
        if not keep.any():
            return c / self.required, self.s2 / self.required, np.zeros(self.lo.size)
        R = np.sqrt(lam[keep])[:, None] * V[:, keep].T
        y = (V[:, keep].T @ h) / np.sqrt(lam[keep])
        u = V[:, keep] @ (y / np.sqrt(lam[keep]))
        if np.any(u < self.lo) or np.any(u > self.hi):
            u = lsq_linear(R, y, bounds=(self.lo, self.hi), method="bvls").x
        d = max(c - 2.0 * float(h @ u) + float(u @ G @ u), 0.0)
        grad = self.s2 - 2.0 * (self.h @ u) + np.einsum("i,kij,j->k", u, self.G, u)
        return d / self.required, grad / self.required, u


def _signatures(ia: int, A: Hypothesis, jac: dict, sig: dict) -> list:
    """A's signature per block: ``sig[ia]`` (flown with its effects), else its linearisation J_A theta_A."""
    if ia in sig:
        return sig[ia]
    n_blocks = len(next(iter(jac.values())))
    return [sum(jac[n][k] @ A.theta[n] for n in A.members) for k in range(n_blocks)]


def directions(hyps: list, jac: dict, sig: dict, d) -> list:
    """Every counting direction (A at its sizes against set B; not when B
    holds every member of A)."""
    out = []
    for ia, A in enumerate(hyps):
        sigs = _signatures(ia, A, jac, sig)
        for ib, B in enumerate(hyps):
            if ia != ib and not set(A.members) <= set(B.members):
                out.append(_direction(ia, ib, B, jac, d, sigs))
    return out


def _direction(ia: int, ib: int, B: Hypothesis, jac: dict, d, sigs: list, family: dict | None = None) -> Direction:
    """Signature ``sigs[k]`` on each block against set B, free inside its bounds."""
    from bench.gap.attribute import candidate

    cs = [candidate(d, n) for n in B.members]
    lo = np.concatenate([np.full(jac[n][0].shape[1], c.lower / c.scale) for n, c in zip(B.members, cs)] + [[]])
    hi = np.concatenate([np.full(jac[n][0].shape[1], c.bound / c.scale) for n, c in zip(B.members, cs)] + [[]])
    s2, h, G = [], [], []
    for k, s in enumerate(sigs):
        JB = np.hstack([jac[n][k] * c.scale for n, c in zip(B.members, cs)] + [np.zeros((s.size, 0))])
        s2.append(float(s @ s))
        h.append(JB.T @ s)
        G.append(JB.T @ JB)
    return Direction(ia, ib, np.array(s2), np.array(h), np.array(G), lo, hi, family)


def worst_case_directions(hyps: list, jac: dict, d) -> list:
    """For every hypothesis B that is another one, A, with one member c
    more: B with c's parameters moved along each one of its directions
    alone (each unit parameter, less its part no block sees, e.g. a nozzle
    turned about its own thrust axis), at the size B gives c (the RMS over
    the directions seen), against A. B's own sizes are the one direction
    the log hid best; the effect may lie along any other, and a plan that
    fires only the valves that direction tilts would not see it."""
    from bench.gap.attribute import candidate

    out = []
    for ib, B in enumerate(hyps):
        for ia, A in enumerate(hyps):
            extra = set(B.members) - set(A.members)
            if ia == ib or not set(A.members) < set(B.members) or len(extra) != 1:
                continue
            (c,) = extra
            cand = candidate(d, c)
            Jc = [J * cand.scale for J in jac[c]]
            lam, V = np.linalg.eigh(sum(J.T @ J for J in Jc))
            seen = V[:, lam > lam.max() * 1e-8]
            P = seen @ seen.T
            size = float(np.linalg.norm(P @ (np.asarray(B.theta[c]) / cand.scale)) / np.sqrt(max(seen.shape[1], 1)))
            if not size > 0:
                continue
            for j, pname in enumerate(cand.params):
                e = P[:, j]
                if np.linalg.norm(e) < 0.3:
                    continue
                u = e / np.linalg.norm(e) * size
                fam = {"member": c, "parameter": pname, "theta": (u * cand.scale).tolist(), "of": ib}
                out.append(_direction(ib, ia, A, jac, d, [J @ u for J in Jc], fam))
    return out


def selection_level(screen_logp: float, rank: int, power: float = POWER) -> float:
    """The distance (noise variances, on the rows the selection trains on)
    at which a member of ``rank`` parameters passes the screening threshold
    (-log10 p = ``screen_logp`` against chi-square with ``rank`` degrees of
    freedom) with probability ``power``: its gain in 2 dLL is a noncentral
    chi-square with that noncentrality."""
    from scipy.optimize import brentq
    from scipy.stats import chi2, ncx2

    x = float(chi2.isf(10.0 ** (-screen_logp), rank))
    hi = max(x, 1.0)
    while ncx2.sf(x, rank, hi) < power:
        hi *= 2.0
    return float(brentq(lambda lam: ncx2.sf(x, rank, lam) - power, 1e-9, hi, xtol=1e-6))


def member_ranks(jac: dict, names: list) -> dict:
    """{name: the rank of its Jacobian over every block} (attribute.numerical_rank, as the selection counts it)."""
    from bench.gap.attribute import numerical_rank

    return {n: max(numerical_rank(np.vstack(jac[n])), 1) for n in names}


def member_levels(jac: dict, names: list, screen_logp: float) -> dict:
    """{name: {"rank", "required_half"}}: each member's rank and the
    distance the selection asks of it on the training half (at least
    DELTA2_95, which the listing asks of any pair)."""
    ranks = member_ranks(jac, names)
    return {n: {"rank": r, "required_half": max(DELTA2_95, selection_level(screen_logp, r))} for n, r in ranks.items()}


def selection_directions(hyps: list, jac: dict, sig: dict, d, dirs: list, screen_logp: float) -> list:
    """The directions of the diagnosis's own tests, each with the distance
    it must reach over the whole plan (``required``: twice the level on the
    training half, which holds half the plan's rows; two passes put every
    firing in both halves):

    - a member c of a set A, at A's sizes, against A without c (free): the
      selection adds c only when its gain beside the others passes the
      screening threshold over c's rank (selection_level, 95 %); so does a
      larger set's extra member along each of its directions
      (worst_case_directions) against the smaller set;
    - any other pair: the answer lists a set that reproduces its fitted
      signature to within DELTA2_95 on the training rows (alternatives.py),
      so DELTA2_95 on the half.

    ``dirs`` (directions and worst_case_directions) get their levels; the
    member tests against sets that are none of the hypotheses are added."""
    levels = member_levels(jac, sorted({n for h in hyps for n in h.members}), screen_logp)
    ranks = {n: v["rank"] for n, v in levels.items()}
    level = {n: v["required_half"] for n, v in levels.items()}
    for dr in dirs:
        A, B = hyps[dr.a], hyps[dr.b]
        extra = set(A.members) - set(B.members)
        c = dr.family["member"] if dr.family is not None else (next(iter(extra)) if len(extra) == 1 else None)
        if c is not None and set(B.members) <= set(A.members):
            dr.required, dr.test = 2.0 * level[c], f"selection: {c} ({ranks[c]} parameters) beside the others"
        else:
            dr.required, dr.test = 2.0 * DELTA2_95, "listing: a set that reproduces the other"
    listed = {frozenset(h.members) for h in hyps}
    out = []
    for ia, A in enumerate(hyps):
        sigs = None
        for c in A.members:
            rest = [n for n in A.members if n != c]
            if frozenset(rest) in listed:
                continue
            sigs = sigs or _signatures(ia, A, jac, sig)
            B = Hypothesis(rest, {n: A.theta[n] for n in rest}, "free")
            dr = _direction(ia, -1, B, jac, d, sigs)
            dr.required, dr.test = 2.0 * level[c], f"selection: {c} ({ranks[c]} parameters) beside the others"
            dr.b_name = B.name
            out.append(dr)
    return out


def evaluate(dirs: list, w: np.ndarray) -> np.ndarray:
    return np.array([dr.distance(np.asarray(w, float))[0] for dr in dirs])


def _solve(dirs: list, T: np.ndarray, V: np.ndarray, max_t: float, max_v: float, target: float | None) -> tuple:
    """(continuous repetitions w, the solver's report): the largest smallest
    distance within the limits, or (``target``) the shortest plan whose
    smallest distance reaches it."""
    from scipy.optimize import minimize

    n = T.size
    scale = max(float(np.max([dr.distance(np.ones(n))[0] for dr in dirs])), 1.0) / n  # distance per repetition
    w0 = np.full(n, 0.5 * min(max_t / T.sum(), max_v / max(V.sum(), 1e-12)))
    if target is None:
        x0 = np.concatenate([w0, [0.0]])
        obj = (lambda x: -x[-1], lambda x: np.concatenate([np.zeros(n), [-1.0]]))
        dist_cons = [
            {
                "type": "ineq",
                "fun": (lambda x, dr=dr: dr.distance(x[:n])[0] / scale - x[-1]),
                "jac": (lambda x, dr=dr: np.concatenate([dr.distance(x[:n])[1] / scale, [-1.0]])),
            }
            for dr in dirs
        ]
    else:
        x0 = np.concatenate([w0 * 2.0, [0.0]])
        obj = (lambda x: float(T @ x[:n]) / max_t, lambda x: np.concatenate([T / max_t, [0.0]]))
        dist_cons = [
            {
                "type": "ineq",
                "fun": (lambda x, dr=dr: (dr.distance(x[:n])[0] - target) / scale),
                "jac": (lambda x, dr=dr: np.concatenate([dr.distance(x[:n])[1] / scale, [0.0]])),
            }
            for dr in dirs
        ]
    lin = [
        {"type": "ineq", "fun": lambda x: 1.0 - float(T @ x[:n]) / max_t, "jac": lambda x: np.append(-T / max_t, 0.0)},
        {
            "type": "ineq",
            "fun": lambda x: 1.0 - float(V @ x[:n]) / max_v,
            "jac": lambda x: np.append(-V / max_v, 0.0),
        },
    ]
    bounds = [(0.0, MAX_REPEATS)] * n + [(None, None)]
    sol = minimize(
        obj[0],
        x0,
        jac=obj[1],
        constraints=dist_cons + lin,
        bounds=bounds,
        method="SLSQP",
        options={"maxiter": 500, "ftol": 1e-9},
    )
    report = {"method": "SLSQP", "success": bool(sol.success), "message": str(sol.message), "iterations": int(sol.nit)}
    return np.clip(sol.x[:n], 0.0, None), report


def _round(
    dirs: list, w: np.ndarray, valve: np.ndarray, pulse_coast: list, T, V, max_t, max_v, target: float | None
) -> np.ndarray:
    """Whole repetitions. With a target: the continuous plan rounded up
    (the distances only grow with repetitions), then shortened (_shorten).
    Without, or when that breaks a limit: rounded down, then filled one
    repetition at a time (_greedy: towards the continuous plan's smallest
    distance, by the capped distances or by _spread), or every valve the
    continuous plan fires once with one pulse and coast, as often as the
    limits allow (_uniform_plans, the fixed characterisation's shape);
    the best two improved by exchanges (_exchange), and with a target
    reached, shortened."""
    near = (valve[:, None] == valve[None, :]) | (w > 1e-3)[None, :]
    if target is not None:
        wi = _shorten(dirs, np.ceil(w - 1e-6), near, T, V, max_v, target)
        if T @ wi <= max_t + 1e-9 and V @ wi <= max_v * (1 + 1e-9):
            return wi
    level = float(evaluate(dirs, w).min())
    starts = [_greedy(dirs, np.floor(w + 1e-6), T, V, max_t, max_v, level, spread) for spread in (False, True)]
    starts += _uniform_plans(w, valve, pulse_coast, T, V, max_t, max_v)

    def score(x) -> tuple:
        d = evaluate(dirs, x)
        return float(d.min()), _spread(d, level)

    best = sorted(starts, key=score, reverse=True)[:2]
    wi = max((_exchange(dirs, x, near, T, V, max_t, max_v, level) for x in best), key=score)
    if target is not None and evaluate(dirs, wi).min() >= target:
        wi = _shorten(dirs, wi, near, T, V, max_v, target)
    return wi


def _shorten(dirs: list, wi: np.ndarray, near: np.ndarray, T, V, max_v: float, target: float) -> np.ndarray:
    """Repetitions taken away (the longest block first) or exchanged for a
    shorter block's (``near``), while every distance stays at ``target``
    and the delta-v within ``max_v`` (when it was)."""
    wi = wi.copy()
    while True:
        best = None
        for i in np.flatnonzero(wi > 0):
            for j in [None, *np.flatnonzero(near[i] & (T < T[i]))]:
                trial = wi.copy()
                trial[i] -= 1
                if j is not None:
                    trial[j] += 1
                if V @ trial > max(max_v, V @ wi) * (1 + 1e-9):
                    continue
                saved = T @ wi - T @ trial
                if (best is None or saved > best[0]) and evaluate(dirs, trial).min() >= target:
                    best = (saved, trial)
        if best is None:
            return wi
        wi = best[1]


def _uniform_plans(w: np.ndarray, valve: np.ndarray, pulse_coast: list, T, V, max_t, max_v) -> list:
    """Every valve the continuous plan ``w`` fires, each once with the same
    pulse and coast, repeated as often as the limits allow: one plan per
    pulse and coast that fits."""
    used = set(valve[w > 1e-3].tolist())
    out = []
    for pc in sorted(set(pulse_coast)):
        base = np.array([1.0 if (v in used and q == pc) else 0.0 for v, q in zip(valve, pulse_coast)])
        t, dv = float(T @ base), float(V @ base)
        r = int(min(max_t / t if t > 0 else 0, max_v / dv if dv > 0 else MAX_REPEATS, MAX_REPEATS) + 1e-9)
        if r >= 1:
            out.append(base * r)
    return out


def _greedy(dirs: list, wi: np.ndarray, T, V, max_t, max_v, level: float, spread: bool) -> np.ndarray:
    """One repetition at a time of the block that adds most, per share of
    the limits it uses, to the distances capped at ``level`` (then to the
    smallest), or with ``spread`` to _spread, while the limits allow."""
    wi = wi.copy()
    cost = T / max_t + V / max_v

    def score(x) -> tuple:
        d = evaluate(dirs, x)
        return (_spread(d, level), 0.0) if spread else (float(np.minimum(d, level).sum()), float(d.min()))

    cur = score(wi)
    while True:
        best = None
        for k in np.flatnonzero(T + T @ wi <= max_t + 1e-9):
            if V[k] + V @ wi > max_v * (1 + 1e-9) or wi[k] >= MAX_REPEATS:
                continue
            trial = wi.copy()
            trial[k] += 1
            sc = score(trial)
            gain = ((sc[0] - cur[0]) / cost[k], (sc[1] - cur[1]) / cost[k])
            if best is None or gain > best[0]:
                best = (gain, k, sc)
        if best is None or best[0] <= (0.0, 0.0):
            return wi
        wi[best[1]] += 1
        cur = best[2]


def _spread(d: np.ndarray, level: float) -> float:
    """How far the distances ``d`` are towards ``level``, every pair
    counted: the sum of log(1e-3 level + min(d, level)). A distance near
    zero costs most, so whole repetitions go first to the pairs no block
    yet separates (the smallest distance alone does not move until every
    such pair has its block)."""
    return float(np.sum(np.log(1e-3 * level + np.minimum(d, level))))


def _exchange(dirs: list, wi: np.ndarray, near: np.ndarray, T, V, max_t, max_v, level: float, sweeps: int = 20):
    """Whole repetitions improved by exchanges: one repetition of a block
    given for one of a block ``near`` (the continuous plan's, or of the
    same valve: ``near[i, j]``), while the limits hold and the smallest
    distance rises (then _spread)."""

    def score(x) -> tuple:
        d = evaluate(dirs, x)
        return float(d.min()), _spread(d, level)

    cur = score(wi)
    for _ in range(sweeps):
        best = None
        for i in np.flatnonzero(wi > 0):
            for j in np.flatnonzero(near[i]):
                if j == i or wi[j] >= MAX_REPEATS:
                    continue
                trial = wi.copy()
                trial[i] -= 1
                trial[j] += 1
                if T @ trial > max_t + 1e-9 or V @ trial > max_v * (1 + 1e-9):
                    continue
                sc = score(trial)
                if sc > cur and (best is None or sc > best[0]):
                    best = (sc, trial)
        if best is None:
            break
        cur, wi = best
    return wi


def fixed_weights(blocks: list) -> np.ndarray:
    """The fixed characterisation as repetitions of the blocks: every valve
    alone for CHARACTERISATION_FIRE_S, then CHARACTERISATION_COAST_S, once."""
    fixed = (CHARACTERISATION_FIRE_S, CHARACTERISATION_COAST_S)
    return np.array([1.0 if (b.pulse_s, b.coast_s) == fixed else 0.0 for b in blocks])


def _all_directions(hyps: list, jac: dict, sig: dict, d, worst_case: bool, screen_logp: float | None) -> list:
    """Every counting direction, with ``worst_case`` every direction of a
    larger set's extra member, and with ``screen_logp`` (the selection
    criterion) each at its test's level."""
    dirs = directions(hyps, jac, sig, d) + (worst_case_directions(hyps, jac, d) if worst_case else [])
    if screen_logp is not None:
        dirs += selection_directions(hyps, jac, sig, d, dirs, screen_logp)
    if not dirs:
        raise ValueError("every hypothesis holds another's members: nothing to separate")
    return dirs


def _fixed_text(fixed_w: np.ndarray, fixed_t: float, fixed_v: float) -> str:
    return (
        f"each valve alone for {CHARACTERISATION_FIRE_S:g} s, then {CHARACTERISATION_COAST_S:g} s without "
        f"firing, after {LEAD_S:g} s closed ({int(fixed_w.sum())} runs, {fixed_t:g} s, {fixed_v:.4g} m/s)"
    )


def _inputs(hyps: list, blocks: list, n_rows: list) -> dict:
    """The hypotheses and the blocks a design is made of, as written to its JSON."""
    return {
        "hypotheses": [
            {"set": h.members, "how": h.how, "parameters": {n: np.asarray(v).tolist() for n, v in h.theta.items()}}
            for h in hyps
        ],
        "delta2_95": DELTA2_95,
        "blocks": [
            {**dataclasses.asdict(b), "lead_s": LEAD_S, "duration_s": b.duration_s, "rows": n}
            for b, n in zip(blocks, n_rows)
        ],
    }


def _criterion(criterion: str | None, target_delta2: float | None, reach: bool) -> str:
    """The criterion design() uses (default: pairwise with a target distance, else selection), its options checked."""
    criterion = criterion or ("pairwise" if target_delta2 is not None else "selection")
    if criterion not in CRITERIA:
        raise ValueError(f"criterion {criterion!r}: one of {', '.join(CRITERIA)}")
    if criterion == "selection" and target_delta2 is not None:
        raise ValueError("a target distance is the pairwise criterion's; with the selection's, reach its levels")
    if criterion == "pairwise" and reach:
        raise ValueError("reaching the levels is the selection criterion's; the pairwise one takes a target distance")
    return criterion


def _objective(criterion: str, target_delta2: float | None, reach: bool) -> str:
    if criterion == "selection":
        if reach:
            return "the shortest plan that makes each of the diagnosis's tests pass 95 % of the time"
        return "the largest smallest share of its level, each test of the diagnosis at its own, within the limits"
    if target_delta2 is not None:
        return f"the shortest plan whose smallest pair distance reaches {target_delta2:g}"
    return "the largest smallest pair distance within the limits"


def committed_screen_logp() -> float:
    """The committed docking calibration's screening threshold (-log10 p)."""
    from bench.gap import null as nullmod

    return float(nullmod.load()["thresholds"]["screen_logp"])


def design(
    hyps: list,
    description: dict,
    max_duration_s: float = DEFAULT_MAX_DURATION_S,
    max_delta_v: float | None = None,
    min_on_time_s: float = DEFAULT_MIN_ON_TIME_S,
    target_delta2: float | None = None,
    worst_case: bool = True,
    passes: int = DEFAULT_PASSES,
    criterion: str | None = None,
    screen_logp: float | None = None,
    reach: bool = False,
) -> dict:
    """The designed plan and the fixed characterisation's, each direction's
    distance for both (module docstring). ``worst_case``: also every
    direction of a larger set's extra member; ``passes`` passes of one
    schedule, each within 1 / passes of the limits. ``criterion``:
    "selection" (each test at its level, selection_directions, from
    ``screen_logp``, default the committed calibration's; ``reach``: the
    shortest plan reaching them) or "pairwise" (one distance, DELTA2_95;
    ``target_delta2``: the shortest plan reaching it; the default then)."""
    import time

    t0 = time.perf_counter()
    criterion = _criterion(criterion, target_delta2, reach)
    if len(hyps) < 2:
        raise ValueError("give at least two hypotheses to separate")
    blocks = catalogue(description, min_on_time_s)
    if not blocks:
        raise ValueError(f"--min-on-time-s {min_on_time_s:g}: longer than every pulse a block fires {PULSES_S}")
    fixed_w = fixed_weights(blocks)
    T = np.array([b.duration_s for b in blocks])
    V = np.array([b.delta_v_mps for b in blocks])
    fixed_t, fixed_v = float(T @ fixed_w), float(V @ fixed_w)
    max_v = float(max_delta_v) if max_delta_v is not None else fixed_v
    if passes * T.min() > max_duration_s:
        raise ValueError(f"--max-duration-s {max_duration_s:g}: shorter than the shortest block times passes")
    jac, sig, n_rows, d = block_jacobians(description, blocks, hyps)
    if criterion == "selection":
        screen_logp = committed_screen_logp() if screen_logp is None else float(screen_logp)
    dirs = _all_directions(hyps, jac, sig, d, worst_case, screen_logp if criterion == "selection" else None)
    target = (1.0 if reach else None) if criterion == "selection" else target_delta2  # selection: in levels
    per_pass = None if target is None else target / passes
    w, solver = _solve(dirs, T, V, max_duration_s / passes, max_v / passes, per_pass)
    share = evaluate(dirs, w)  # of each direction's level, one pass
    valve = np.array([b.valve for b in blocks])
    pulse_coast = [(b.pulse_s, b.coast_s) for b in blocks]
    wi = _round(dirs, w, valve, pulse_coast, T, V, max_duration_s / passes, max_v / passes, per_pass)
    if not wi.any():
        raise ValueError("no block fits the limits")
    summary = {"criterion": criterion, "target": target_delta2}
    out = {
        "objective": _objective(criterion, target_delta2, reach),
        "criterion": criterion,
        "limits": {
            "max_duration_s": float(max_duration_s),
            "max_delta_v_mps": max_v,
            "max_delta_v_source": "given" if max_delta_v is not None else "the fixed characterisation's",
            "min_on_time_s": float(min_on_time_s),
        },
        **_inputs(hyps, blocks, n_rows),
        "passes": int(passes),
        "designed": _plan_summary(dirs, hyps, blocks, wi, T, V, passes, **summary),
        "designed_continuous": {
            "repeats": w.tolist(),
            "delta2": (share * [dr.required for dr in dirs]).tolist(),
            "level_min": float(passes * share.min()) if criterion == "selection" else None,
            "solver": solver,
        },
        "fixed": _plan_summary(dirs, hyps, blocks, fixed_w, T, V, **summary),
        "fixed_plan": _fixed_text(fixed_w, fixed_t, fixed_v),
        "elapsed_s": time.perf_counter() - t0,
    }
    if criterion == "selection":
        names = sorted({n for h in hyps for n in h.members})
        out.update(screen_logp=screen_logp, power=POWER, levels=member_levels(jac, names, screen_logp))
    if target is not None:
        out["target_reached"] = bool(out["designed"]["level_min"] >= 1.0 - 1e-9)
    return out


def continuous_bound(
    hyps: list,
    description: dict,
    max_duration_s: float,
    max_delta_v: float,
    screen_logp: float | None = None,
    passes: int = DEFAULT_PASSES,
    min_on_time_s: float = DEFAULT_MIN_ON_TIME_S,
) -> dict:
    """The selection criterion's continuous problem alone (no whole runs,
    which cost most on long plans): within the limits, the largest
    smallest share of the levels (``level_max``), an upper bound on every
    plan of whole runs from the blocks in ``passes`` passes (the problem is
    convex and holds them all); when it reaches 1, the shortest continuous
    plan that does (``duration_s``, ``delta_v_mps``), a lower bound on
    theirs."""
    blocks = catalogue(description, min_on_time_s)
    T = np.array([b.duration_s for b in blocks])
    V = np.array([b.delta_v_mps for b in blocks])
    jac, sig, _, d = block_jacobians(description, blocks, hyps)
    thr = committed_screen_logp() if screen_logp is None else float(screen_logp)
    dirs = _all_directions(hyps, jac, sig, d, True, thr)
    lim = (max_duration_s / passes, max_delta_v / passes)
    w, solver = _solve(dirs, T, V, *lim, None)
    out = {"limits": [max_duration_s, max_delta_v], "level_max": float(passes * evaluate(dirs, w).min())}
    out.update(reached=out["level_max"] >= 1.0 - 1e-6, solver=solver)
    if out["reached"]:
        w, solver = _solve(dirs, T, V, *lim, 1.0 / passes)
        ok = evaluate(dirs, w).min() * passes >= 1.0 - 1e-3
        out.update(duration_s=float(passes * T @ w) if ok else None, delta_v_mps=float(passes * V @ w) if ok else None)
    return out


def pair_rows(dirs: list, hyps: list, d2: np.ndarray) -> list:
    """One row per counting direction; a family (worst_case_directions) as
    one row, its smallest distance and the direction that gives it. Each
    row: the whole plan's distance ``delta2``; under the selection
    criterion the diagnosis's ``test``, the distance it asks of each half
    (``required_half``), the half's (``delta2_half``) and ``reached``."""
    rows, fams = [], {}
    for dr, x in zip(dirs, d2):
        row = {"a": hyps[dr.a].name, "b": dr.b_name or hyps[dr.b].name, "delta2": float(x)}
        if dr.required != 1.0:
            row.update(
                test=dr.test,
                required_half=0.5 * dr.required,
                delta2_half=0.5 * float(x),
                reached=bool(x >= dr.required * (1 - 1e-9)),
            )
        if dr.family is None:
            rows.append(row)
            continue
        key = (dr.a, dr.b)
        if key not in fams or x < fams[key]["delta2"]:  # one member: one level
            f = dr.family
            size = float(np.linalg.norm(f["theta"]))
            row["a"] = f"{hyps[dr.a].name}, any one {f['member']} direction at {size:.3g}"
            row["worst"] = {"parameter": f["parameter"], "theta": f["theta"], "member": f["member"], "of": f["of"]}
            fams[key] = row
    rows += list(fams.values())
    return [dict(r, separated_95=bool(r["delta2"] >= DELTA2_95)) for r in rows]


def _plan_summary(
    dirs: list,
    hyps: list,
    blocks: list,
    w_pass: np.ndarray,
    T,
    V,
    passes: int = 1,
    criterion: str = "pairwise",
    target: float | None = None,
) -> dict:
    """A plan of ``passes`` passes of the repetitions ``w_pass``: its cost,
    distances (of the whole plan), how far it is to its levels
    (``level_min``: the smallest share of a test's level under the
    selection criterion; the smallest distance over DELTA2_95, or over the
    target, under the pairwise one) and schedule."""
    w = passes * w_pass
    share = evaluate(dirs, w)
    d2 = share * np.array([dr.required for dr in dirs])
    level = float(share.min()) if criterion == "selection" else float(d2.min()) / (target or DELTA2_95)
    return {
        "duration_s": float(T @ w),
        "delta_v_mps": float(V @ w),
        "runs": int(w.sum()),
        "repeats": {i: int(round(x)) for i, x in enumerate(w) if x > 0},
        "delta2_min": float(d2.min()),
        "level_min": level,
        "pairs": pair_rows(dirs, hyps, d2),
        "schedule": schedule(blocks, w_pass, passes),
    }


def schedule(blocks: list, w: np.ndarray, passes: int = 1) -> list:
    """The plan run by run: each run from rest, its valve's open and close
    times from the run's start; the pass of ``w`` repetitions flown
    ``passes`` times."""
    runs = []
    for p in range(passes):
        for k in np.flatnonzero(w > 0):
            b = blocks[k]
            for _ in range(int(round(w[k]))):
                runs.append(
                    {
                        "run": len(runs),
                        "pass": p,
                        "duration_s": b.duration_s,
                        "valves": {str(b.valve): [[LEAD_S, LEAD_S + b.pulse_s]]},
                        "block": int(k),
                    }
                )
    return runs


def plan_segments(plan: dict, n_valves: int) -> list:
    """The designed plan's runs as the bench's vehicle simulator flies them."""
    segs = []
    for r in plan["schedule"]:
        ((v, [[a, b]]),) = r["valves"].items()
        segs.append(run_segment(int(v), b - a, r["duration_s"] - b, n_valves))
    return segs


# --- checked: the plan flown -------------------------------------------------------------------


def flown_distances(description: dict, segments: list, hyps: list, truth: int, seed: int = 0) -> dict:
    """The plan ``segments`` flown by the described vehicle on the bench's
    plant with hypothesis ``truth``'s effects at its sizes and without them
    (the same seed: common random numbers, as bench/campaigns/gap/separability.py
    twin_logs). On that flight, s the whitened difference of the two on
    every row, and for every other hypothesis B not holding every member of
    the truth: ``delta2`` = |(I - P_B) s|^2, what the design predicts; and
    ``delta2_fitted`` = |(I - P_B) P_A s|^2, the true set's fit of s first
    (separability.set_separability_of_logs), which leaves out the part of
    s the true set's linearisation does not reach."""
    from bench.gap.attribute import signature
    from bench.gap.detection import context
    from bench.gap.load import prepare
    from bench.sim.vehicle_sim import simulate

    A = hyps[truth]
    log1, _ = simulate(description, segments, effects_of(A), seed=seed, with_truth=False)
    log0, _ = simulate(description, segments, {}, seed=seed, with_truth=False)
    ctx0 = all_rows(context(prepare(log0)))
    ctx1 = context(prepare(log1))
    if ctx1.nominal.white.shape != ctx0.nominal.white.shape or ctx1.ch.e0.shape != ctx0.ch.e0.shape:
        raise ValueError("the flights with and without the effects differ in their streams' lengths")
    ok = ctx0.train_nav
    s = whitened_rows(ctx0, ok) - whitened_rows(ctx1, ok)  # as J theta: what the correction removes
    names = sorted({n for h in hyps for n in h.members})
    jac = {n: signature(ctx0, n, ok[ok])[0] for n in names}
    _, p = _fit_set(ctx0, jac, A.members, s)
    out = {"truth": A.name, "seed": int(seed), "lambda": float(s @ s), "outside_truth2": float(np.sum((s - p) ** 2))}
    out["pairs"] = []
    for ib, B in enumerate(hyps):
        if ib == truth or set(A.members) <= set(B.members):
            continue
        _, q = _fit_set(ctx0, jac, B.members, s)
        _, qp = _fit_set(ctx0, jac, B.members, p)
        out["pairs"].append(
            {
                "a": A.name,
                "b": B.name,
                "delta2": float(np.sum((s - q) ** 2)),
                "delta2_fitted": float(np.sum((p - qp) ** 2)),
            }
        )
    return out


def parse_sets(hypotheses: str | None, hypothesis: list | None) -> list:
    """Named sets: ``--hypotheses a,b+c`` and repeated ``--hypothesis a+b``."""
    texts = [t for t in (hypotheses or "").split(",") if t.strip()] + list(hypothesis or [])
    sets = []
    for t in texts:
        members = [m.strip() for m in t.split("+") if m.strip()]
        if not members:
            raise ValueError(f"hypothesis {t!r}: name one or more candidates joined by '+'")
        if len(set(members)) != len(members):
            raise ValueError(f"hypothesis {t!r}: a candidate named twice")
        if any(set(members) == set(s) for s in sets):
            raise ValueError(f"hypothesis {t!r}: named twice")
        sets.append(members)
    return sets


def hypotheses_for(log, diagnosis: dict | None = None, named: list | None = None) -> tuple:
    """(hypotheses at their sizes, where they came from): the named sets,
    or the diagnosis's answer and the sets it lists (the given diagnosis,
    else the log diagnosed now)."""
    if named:
        if len(named) < 2:
            raise ValueError("name at least two hypotheses to separate")
        return fit_hypotheses(log, [(list(s), None) for s in named]), "named"
    if diagnosis is None:
        from bench.gap.diagnose import diagnose, public

        diagnosis = public(diagnose(log))
    sets = sets_of_diagnosis(diagnosis)
    if len(sets) < 2:
        raise ValueError(
            f"the diagnosis ({diagnosis.get('verdict')}) lists no set it cannot tell from its answer: nothing to "
            "separate (name the sets with --hypotheses)"
        )
    return fit_hypotheses(log, sets), f"diagnosis ({diagnosis.get('verdict')})"


def plot(result: dict, path) -> None:
    """Distance per pair, designed against fixed, and both schedules."""
    import textwrap

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(10, 10), gridspec_kw={"height_ratios": [1.2, 1, 1]})
    ax = axes[0]
    des, fix = result["designed"]["pairs"], result["fixed"]["pairs"]
    labels = ["\n".join(textwrap.wrap(f"{p['a']} vs {p['b']}", 40)) for p in des]
    x = np.arange(len(des))
    ax.bar(x - 0.2, [p["delta2"] for p in des], 0.4, label=f"designed ({result['designed']['duration_s']:.0f} s)")
    ax.bar(
        x + 0.2,
        [p["delta2"] for p in fix],
        0.4,
        label=f"fixed characterisation ({result['fixed']['duration_s']:.0f} s)",
    )
    if result.get("flown"):
        for k, (key, dx) in enumerate((("designed", -0.2), ("fixed", 0.2))):
            fl = {(p["a"], p["b"]): p["delta2"] for f in result["flown"][key] for p in f["pairs"]}
            ys = [fl.get((p["a"], p["b"]), np.nan) for p in des]
            ax.plot(x + dx, ys, "kx", ms=9, label="flown" if k == 0 else None)
    if "required_half" in des[0]:
        # Each direction's own level, on the whole plan (twice the half's).
        ax.plot(x, [2.0 * p["required_half"] for p in des], "r_", ms=22, mew=2, label="the test's level (whole plan)")
    else:
        ax.axhline(result["delta2_95"], color="r", ls="--", label="10.8: separated 95 % of the time")
    ax.set_yscale("log")
    ax.set_xlim(-0.8, len(des) - 0.2)
    ax.set_xticks(x, labels, fontsize=7)
    ax.set_ylabel("distance delta2 [noise variances]")
    ax.legend(fontsize=8)
    ax.set_title("predicted distance per pair (hypothesis at its sizes vs the other set)")
    for ax, key in zip(axes[1:], ("designed", "fixed")):
        t0 = 0.0
        for r in result[key]["schedule"]:
            for v, spans in r["valves"].items():
                for a, b in spans:
                    ax.barh(int(v), b - a, left=t0 + a, height=0.6, color="C0")
            ax.axvline(t0, color="0.8", lw=0.5)
            t0 += r["duration_s"]
        n = len(result["hypotheses"][0]["parameters"].get("thrust_loss", [])) or None
        ax.set_ylabel("valve")
        if n:
            ax.set_ylim(-0.5, n - 0.5)
        p = result[key]
        ax.set_title(f"{key}: {p['runs']} runs from rest, {p['duration_s']:.0f} s, delta-v {p['delta_v_mps']:.3g} m/s")
    axes[-1].set_xlabel("time, runs end to end [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# What each field of the plan's JSON holds.
FIELDS = {
    "objective": "what was maximised or minimised",
    "limits": "the user's limits: plan duration [s], delta-v [m/s], shortest valve opening [s]",
    "hypotheses": "the sets to separate, each at its sizes on the log (parameters in the candidates' units)",
    "delta2_95": "the distance at which two hypotheses are told apart 95 % of the time [noise variances]",
    "criterion": "selection: each direction at the level the diagnosis's own test asks of it on the training "
    "half; pairwise: every direction against one distance",
    "screen_logp": "the screening threshold (-log10 p) the selection levels are computed from",
    "power": "the probability with which each test should pass at its level",
    "levels": "each member's rank over the blocks and the distance the selection asks of it on a half",
    "blocks": "the elementary blocks: valve, pulse_s, coast_s after lead_s closed, delta_v_mps, duration_s",
    "designed": "the designed plan: duration_s, delta_v_mps, runs, repeats per block, level_min (the smallest "
    "share of a level reached), predicted distance per pair (a at its sizes vs set b; under the selection "
    "criterion with the test, required_half, delta2_half and reached), and schedule: each run from rest, every valve's [open, close] "
    "times [s] from the run's start",
    "designed_continuous": "the optimiser's repetitions before rounding, and their distances",
    "fixed": "the fixed characterisation plan, evaluated the same way",
    "description": "the described vehicle the plan is for (the log's own, every default resolved)",
    "flown": "with --check: the plans flown on the bench's plant with each hypothesis's effects and without "
    "(common random numbers), the distance measured on the flight",
}


def check(result: dict, hyps: list, description: dict, seed: int = 0) -> dict:
    """Both plans flown (flown_distances) with each hypothesis that has a
    pair to separate as the truth, and with each family's worst direction
    in the designed plan (worst_case_directions): {"designed": [...],
    "fixed": [...]}."""
    n_valves = len(description["vehicle"]["thrusters"])
    truths = [i for i, A in enumerate(hyps) if any(not set(A.members) <= set(B.members) for B in hyps if B is not A)]
    against = list(hyps)
    if result.get("criterion") == "selection":  # each member's own test: its set without it, where none is listed
        truths = [i for i, A in enumerate(hyps) if A.members]
        listed = {frozenset(h.members) for h in hyps}
        for A in hyps:
            for c in A.members:
                rest = [n for n in A.members if n != c]
                if frozenset(rest) not in listed:
                    listed.add(frozenset(rest))
                    against.append(Hypothesis(rest, {}, "free"))
    out = {}
    for key in ("designed", "fixed"):
        segs = plan_segments(result[key], n_valves)
        out[key] = []
        for i in truths:
            f = flown_distances(description, segs, against, i, seed)
            A = set(hyps[i].members)
            f["pairs"] = [p for p in f["pairs"] if p["b"] in {h.name for h in hyps} or _one_less(A, p["b"])]
            out[key].append(f)
        for row in result["designed"]["pairs"]:
            if "worst" not in row:
                continue
            w = row["worst"]
            B = hyps[w["of"]]
            theta = {**B.theta, w["member"]: np.asarray(w["theta"])}
            A = next(h for h in hyps if h.name == row["b"])
            variant = Hypothesis(B.members, theta, f"{w['member']} along {w['parameter']} alone")
            f = flown_distances(description, segs, [variant, A], 0, seed)
            f["truth"] = row["a"] + f" (worst: {w['parameter']})"
            for p in f["pairs"]:
                p["a"] = row["a"]
            out[key].append(f)
    return out


def _one_less(members: set, name: str) -> bool:
    """Set ``name`` (a Hypothesis name) is ``members`` less one of them."""
    rest = set() if name == Hypothesis([], {}).name else set(name.split(" + "))
    return rest < members and len(members - rest) == 1


def diagnosis_screen_logp(diagnosis: dict | None) -> float | None:
    """The screening threshold a diagnosis was judged by (its
    statistics.screen_logp_threshold), None when it has none."""
    import math

    thr = ((diagnosis or {}).get("statistics") or {}).get("screen_logp_threshold")
    if isinstance(thr, (int, float)) and not isinstance(thr, bool) and math.isfinite(thr) and thr > 0:
        return float(thr)
    return None


def separate(
    log,
    diagnosis: dict | None = None,
    named: tuple = (None, None),
    max_duration_s: float = DEFAULT_MAX_DURATION_S,
    max_delta_v: float | None = None,
    min_on_time_s: float = DEFAULT_MIN_ON_TIME_S,
    target_delta2: float | None = None,
    check_seed: int | None = None,
    worst_case: bool = True,
    passes: int = DEFAULT_PASSES,
    criterion: str | None = None,
    reach: bool = False,
) -> dict:
    """`proxops plan LOG --separate`: the hypotheses (``named``: the
    ``--hypotheses`` text and the ``--hypothesis`` list; else the given or a
    fresh diagnosis), the designed and the fixed plan for the log's
    described vehicle, and with ``check_seed`` both flown (check). Under
    the selection criterion the levels are the diagnosis's screening
    threshold (else the committed calibration's)."""
    named_sets = parse_sets(*named)
    if diagnosis is None and not named_sets:
        from bench.gap.diagnose import diagnose, public

        diagnosis = public(diagnose(log))
    hyps, source = hypotheses_for(log, diagnosis, named_sets)
    description = description_of(log)
    res = design(
        hyps,
        description,
        max_duration_s,
        max_delta_v,
        min_on_time_s,
        target_delta2,
        worst_case,
        passes,
        criterion,
        None if named_sets else diagnosis_screen_logp(diagnosis),
        reach,
    )
    res["hypotheses_from"] = source
    res["description"] = description
    if check_seed is not None:
        res["flown"] = check(res, hyps, description, check_seed)
    res["fields"] = {k: v for k, v in FIELDS.items() if k in res or k == "flown"}
    return res


def docking_tilt(
    seed: int = 5, tilt_rad: float = 0.03, diagnose_flights: bool = False, criterion: str = "pairwise"
) -> dict:
    """A docking log (bench/sim/reality.py) with thrust losses of 0.06 and
    0.04 on valves 3 and 6 and nozzle tilts of ``tilt_rad`` on the same
    valves, diagnosed; plans designed from its answer (for every direction
    of the hidden member, for the listed sizes alone, and for every
    direction in two passes within twice the limits) and the fixed
    characterisation; the true effects flown on each (seed ``seed``),
    their distance from a loss alone, and with ``diagnose_flights`` the
    diagnosis of each flight (docs/GAP.md)."""
    from bench.gap.diagnose import diagnose, public
    from bench.sim.reality import simulate_log_with_key
    from bench.sim.vehicle_sim import simulate

    loss = [0.0, 0.0, 0.0, 0.06, 0.0, 0.0, 0.04, 0.0]
    phi = np.zeros((8, 3))
    phi[3], phi[6] = [tilt_rad, 0.0, 0.0], [0.0, tilt_rad, 0.0]
    effects = {"thrust_loss": loss, "thruster_misalignment": phi.ravel().tolist()}
    log, _ = simulate_log_with_key(seed, effects, 120.0, with_truth=False)
    out = public(diagnose(log))
    sets = sets_of_diagnosis(out)
    hyps = fit_hypotheses(log, sets)
    description = description_of(log)
    truth = Hypothesis(sets[-1][0], {k: np.asarray(v) for k, v in effects.items()}, "the true effects")
    rows = {"answer": {"verdict": out["verdict"], "sets": [s for s, _ in sets]}}
    limits = DEFAULT_MAX_DURATION_S, None
    fixed_v = None
    for name, worst, passes, scale in (
        ("every direction", True, DEFAULT_PASSES, 1),
        ("every direction, one pass", True, 1, 1),
        ("listed sizes", False, DEFAULT_PASSES, 1),
        ("every direction, twice the limits", True, DEFAULT_PASSES, 2),
    ):
        res = design(
            hyps,
            description,
            scale * limits[0],
            None if fixed_v is None else scale * fixed_v,
            passes=passes,
            worst_case=worst,
            criterion=criterion,
        )
        fixed_v = res["fixed"]["delta_v_mps"]
        for key in ("designed", "fixed") if name == "every direction" else ("designed",):
            segs = plan_segments(res[key], len(description["vehicle"]["thrusters"]))
            (pair,) = flown_distances(description, segs, [truth, hyps[0]], 0, seed)["pairs"]
            row = {
                "duration_s": res[key]["duration_s"],
                "delta_v_mps": res[key]["delta_v_mps"],
                "predicted_delta2_min": res[key]["delta2_min"],
                "true_effects_delta2": pair["delta2"],
            }
            if diagnose_flights:
                from bench.gap.answers import which_text

                flown, _ = simulate(description, segs, effects_of(truth), seed=seed, with_truth=False)
                row["diagnosis_of_the_flight"] = which_text(public(diagnose(flown)))
            rows[f"designed ({name})" if key == "designed" else key] = row
    return rows


def main(argv=None) -> None:
    import argparse
    import json

    ap = argparse.ArgumentParser(description="the designed plan on a docking log with a tilt beside a loss")
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--tilt", type=float, default=0.03, help="nozzle tilt of valves 3 and 6 [rad]")
    ap.add_argument("--diagnose-flights", action="store_true", help="diagnose each flown plan (minutes)")
    ap.add_argument("--criterion", choices=CRITERIA, default="pairwise", help="the design's criterion")
    a = ap.parse_args(argv)
    print(json.dumps(docking_tilt(a.seed, a.tilt, a.diagnose_flights, a.criterion), indent=1))


if __name__ == "__main__":
    main()
