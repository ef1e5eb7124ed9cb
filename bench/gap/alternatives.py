"""The sets of effects the data cannot tell from the answer's.

Forward selection (bench/gap/select.py) names one set; where the data do
not separate it from others, the answer lists those others. Three kinds,
all on the screening Jacobians of the training rows (the linearised
problem), every parameter inside its physical bounds:

- look-alikes: one member swapped for a candidate that reproduces the
  set's fitted signature to within DELTA2_95 noise variances
  (_look_alikes);
- sets that explain as well (_explaining): any set of at most
  MAX_EFFECTS candidates beside which the answer's members pass no
  screening threshold (where forward selection stops), and that has no
  smaller such set inside it;
- hidden members (_hides): one more candidate that can sit beside
  the answer, or beside one of those sets, carrying a share of the gap
  worth naming while the set's members, refitted, absorb it.

DELTA2_95 (10.8 noise variances, bench/campaigns/gap/separability.py) is the
distance at which two hypotheses are told apart from one run with 95 %
probability.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

from bench.gap.attribute import DELTA2_95, Context, screen_logp, training_residuals
from bench.gap.select import MAX_EFFECTS, bounded_lstsq, stacked, two_dll

# A hidden member carries at least this share of the set's fitted signature
# (in noise variances: a quarter is half the gap's amplitude), and at least
# DELTA2_95: a share of the gap worth naming.
HIDDEN_SHARE = 0.25


class _Columns:
    """A candidate's Jacobian columns in the reduced problem (_reduced)."""

    def __init__(self, J_u: np.ndarray):
        self.J_u = J_u


def screened(fits: list) -> dict:
    """{name: fit} of the candidates with a screening Jacobian and a finite
    screen."""
    return {f.name: f for f in fits if getattr(f, "J_u", None) is not None and np.isfinite(f.screen_bic)}


def _reduced(fits_by: dict, e0: np.ndarray) -> tuple:
    """({name: columns}, z): every candidate's screening Jacobian and the
    training residual e0 reduced to the triangle of their joint QR, [R, z] =
    Q^T [J, e0]. Every fit of a subset of the columns is the same on the
    P + 1 rows of R as on the thousands of J (|e0 + J_S u|^2 = |z + R_S u|^2,
    |e0| = |z|), and R_S has J_S's singular values: hundreds of sets are
    compared for the cost of one QR."""
    from scipy.linalg import qr

    names = list(fits_by)
    J = np.hstack([fits_by[n].J_u for n in names] + [e0[:, None]])
    (R,) = qr(J, mode="r", check_finite=False)
    R = np.triu(R[: J.shape[1]])
    edges = np.cumsum([0] + [fits_by[n].J_u.shape[1] for n in names])
    return {n: _Columns(R[:, a:b]) for n, a, b in zip(names, edges[:-1], edges[1:])}, R[:, -1]


def _fitted(ctx: Context, red: dict, names: list, z: np.ndarray) -> tuple:
    """(J, lo, hi, sig): the names' stacked reduced columns, their bounds,
    and the signature of their bounded fit to the reduced residual z."""
    J, lo, hi = stacked(ctx, red, names)
    return J, lo, hi, J @ bounded_lstsq(J, -z, lo, hi)


def _look_alikes(ctx: Context, red: dict, z: np.ndarray, names: list, delta2: float) -> list:
    """The sets that differ from ``names`` by one member and reproduce the
    set's fitted signature to within ``delta2`` noise variances (inside
    their physical bounds). [{"replace", "with", "signature_distance2"}]."""
    _, _, _, sig = _fitted(ctx, red, names, z)
    out = []
    for m in names:
        for c in red:
            if c in names:
                continue
            alt = [c if n == m else n for n in names]
            Ja, la, ha = stacked(ctx, red, alt)
            r = sig - Ja @ bounded_lstsq(Ja, sig, la, ha)
            d2 = float(r @ r)
            if d2 < delta2:
                out.append({"replace": m, "with": c, "signature_distance2": d2})
    return sorted(out, key=lambda a: a["signature_distance2"])


def _hiding_directions(J: np.ndarray, Jc: np.ndarray) -> list:
    """The three directions of c's parameters whose signature the set's
    columns J reproduce best against its size: the principal directions
    between c's column space and the set's (the eigenvectors of
    Uc^T (I - P_S) Uc with the smallest eigenvalues, Uc an orthonormal
    basis of c's signatures: the part the set cannot reproduce, per unit
    of signature)."""
    U, sv, _ = np.linalg.svd(J, full_matrices=False)
    U = U[:, sv > sv[0] * 1e-10]
    Uc, sc, Vct = np.linalg.svd(Jc, full_matrices=False)
    keep = sc > sc[0] * 1e-8
    Uc, sc, Vct = Uc[:, keep], sc[keep], Vct[keep]
    perp = Uc - U @ (U.T @ Uc)
    _, A = np.linalg.eigh(perp.T @ perp)
    return [Vct.T @ (a / sc) for a in A.T[:3]]


def hiding_fits(J, lo, hi, Jc, lc, hc, sig: np.ndarray, share: float) -> list:
    """[(d2, u, u_c)]: candidate c (columns Jc, bounds lc..hc) carrying
    ``share`` noise variances of signature beside a set (columns J, bounds
    lo..hi) whose fitted signature is ``sig``: c's parameters u_c, the
    set's refitted u, and d2 = |sig - Jc u_c - J u|^2, the part the set
    cannot absorb. Tried along c's bounded fit to ``sig`` and the three
    directions that hide best (_hiding_directions), each sign, clipped to
    c's bounds and scaled to the share; a direction that leaves the bounds
    at that size is not kept. All in scaled units."""
    tries = [bounded_lstsq(Jc, sig, lc, hc)]
    for v in _hiding_directions(J, Jc):
        tries += [v, -v]
    out = []
    for v in tries:
        v = np.clip(v, np.minimum(lc, 0), np.maximum(hc, 0))
        size2 = float(np.sum((Jc @ v) ** 2))
        if not size2 > 0:
            continue
        u_c = v * np.sqrt(share / size2)
        if np.any(u_c < lc - 1e-12) or np.any(u_c > hc + 1e-12):
            continue
        rest = sig - Jc @ u_c
        u = bounded_lstsq(J, rest, lo, hi)
        r = rest - J @ u
        out.append((float(r @ r), u, u_c))
    return out


def _hides(ctx: Context, red: dict, base: tuple, c: str, delta2: float) -> dict | None:
    """Whether candidate ``c`` can sit beside a set (``base``: _fitted)
    carrying a share of the gap worth naming (HIDDEN_SHARE of the set's
    fitted signature, at least ``delta2``) while the set's members,
    refitted inside their bounds, reproduce the set's fitted signature less
    c's part to within ``delta2`` (hiding_fits, the best of its
    directions). A nozzle tilt beside a thrust loss on a docking approach
    is the usual one: the loss of the same valves absorbs it.
    {"add", "hidden_signature2", "signature_distance2"} or None."""
    J, lo, hi, sig = base
    share = max(delta2, HIDDEN_SHARE * float(sig @ sig))
    Jc, lc, hc = stacked(ctx, red, [c])
    d2 = min((f[0] for f in hiding_fits(J, lo, hi, Jc, lc, hc, sig, share)), default=np.inf)
    return {"add": c, "hidden_signature2": share, "signature_distance2": d2} if d2 < delta2 else None


def _explaining(ctx: Context, red: dict, z: np.ndarray, names: list, threshold_logp: float) -> list:
    """The sets of at most MAX_EFFECTS candidates forward selection
    could have stopped at instead of the answer ``names``: the answer's
    members not in a set B, fitted beside B, pass no screening threshold
    (their conditional statistic, -log10 p of their gain in 2 dLL against
    chi-square with the rank they add, stays at or below
    ``threshold_logp``, where selection stops); and no smaller such set lies
    inside B (every member is needed: the answer itself is such a set, so
    none of its supersets is listed here). Had the noise or the order of
    entry been otherwise, selection could have named B. These reach sets
    two steps from the answer (one member swapped and one dropped), which
    look-alikes do not. [{"set", "logp_beside"}], the best explaining
    first."""
    memo = {}

    def dll(ns) -> tuple:
        k = tuple(sorted(ns))
        if k not in memo:
            memo[k] = two_dll(ctx, red, list(k), z)
        return memo[k]

    found = {frozenset(names): 0.0}
    for k in range(1, MAX_EFFECTS + 1):
        for B in combinations(sorted(red), k):
            if any(S < set(B) for S in found):
                continue
            (t, r), (tu, ru) = dll(B), dll(set(B) | set(names))
            lp = screen_logp(tu - t, ru - r) if ru > r else 0.0
            if lp <= threshold_logp:
                found[frozenset(B)] = lp
    out = [
        {"set": [n for n in names if n in S] + sorted(S - set(names)), "logp_beside": lp}
        for S, lp in found.items()
        if S != frozenset(names)
    ]
    return sorted(out, key=lambda a: a["logp_beside"])


def alternative_sets(ctx: Context, fits: list, names: list, threshold_logp: float) -> list:
    """Every set the answer ``names`` cannot be told from, each once, in
    order: its look-alikes, the sets that explain as well, and the hidden
    members beside the answer and beside each of those sets (at most
    MAX_EFFECTS + 1 members). Each entry {"set", ...} says why it is
    listed: "replace"/"with" (a look-alike), "logp_beside" (explains as
    well), "add" (a hidden member, with "to": the set it hides beside)."""
    fits_by = screened(fits)
    if not names or not all(n in fits_by for n in names):
        return []
    e0, _ = training_residuals(ctx)
    red, z = _reduced(fits_by, e0)
    seen = {frozenset(names)}
    out = []

    def keep(entry: dict) -> None:
        if frozenset(entry["set"]) not in seen:
            seen.add(frozenset(entry["set"]))
            out.append(entry)

    for a in _look_alikes(ctx, red, z, names, DELTA2_95):
        keep({"set": [a["with"] if n == a["replace"] else n for n in names], **a})
    explaining = _explaining(ctx, red, z, names, threshold_logp)
    for a in explaining:
        keep(a)
    for base in [list(names)] + [a["set"] for a in explaining]:
        if len(base) > MAX_EFFECTS:
            continue
        fitted = _fitted(ctx, red, base, z)
        for c, f in fits_by.items():
            if c in base or not f.screen_logp > threshold_logp or frozenset(base + [c]) in seen:
                continue
            h = _hides(ctx, red, fitted, c, DELTA2_95)
            if h is not None:
                keep({"set": base + [c], "to": base, **h})
    return out
