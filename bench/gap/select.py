"""Several effects at once: which set of in-library effects the data support.

Forward selection on the screening Jacobians (bench/gap/attribute.py), then
one joint refit of the chosen set with the full filter:

1. Start from the empty set. For every candidate not yet chosen, fit it
   together with the chosen ones (the linearised GLR over the stacked
   Jacobians, every candidate inside its physical bounds) and take its
   conditional statistic: the gain in 2 dLL over the chosen set alone, as
   -log10 p against chi-square with the rank it adds. The best one joins
   when that statistic passes the null-calibrated screening threshold (the
   same threshold that detects a gap: with the right set chosen, what is
   left is the null's noise, and the threshold holds its false-alarm rate
   for the next step). After each addition a member whose statistic beside
   all the others no longer passes is dropped, the weakest first, and not
   tried again (stepwise selection). At most MAX_EFFECTS effects.
2. Refit the chosen set jointly with the full filter (scipy least_squares,
   every residual a full replay with the members' corrections added) on the
   training rows of both channels; a set of dynamics-only members as one
   such candidate alone is refitted (chord steps on the exact dynamics
   channel, _solve).

Each member's share: the held-out shrink of the joint fit, and what it
adds beside the others (the joint shrink minus the shrink with that member's
parameters set to zero and the others kept).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bench.gap.attribute import (
    Context,
    Fit,
    candidate,
    chord_fit,
    fit_sigma,
    numerical_rank,
    run_pass,
    screen_logp,
    training_residuals,
)

MAX_EFFECTS = 3


@dataclass
class SetFit:
    names: list
    theta: dict  # name -> parameters
    sigma: dict
    after_nav: object = None
    after_dyn: np.ndarray | None = None
    dll_train: float = float("nan")
    steps: list = field(default_factory=list)  # [{"effect", "conditional_logp", "rank_added"}]

    def corrections(self, d, theta: dict | None = None):
        from bench.gap.replay import Corrections

        th = theta or self.theta
        c = Corrections()
        for n in self.names:
            c = c.add(candidate(d, n).corrections(th[n], d))
        return c


def bounded_lstsq(J: np.ndarray, y: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """argmin |J u - y| with lo <= u <= hi (plain least squares when that
    already lies inside)."""
    u, *_ = np.linalg.lstsq(J, y, rcond=None)
    if np.all(u >= lo) and np.all(u <= hi):
        return u
    from scipy.optimize import lsq_linear

    return lsq_linear(J, y, bounds=(lo, hi)).x


def stacked(ctx: Context, fits_by: dict, names: list) -> tuple:
    """(J, lower, upper) of the names' stacked screening Jacobians, in units
    of each candidate's scale."""
    J = np.hstack([fits_by[n].J_u for n in names])
    lo = np.concatenate(
        [np.full(fits_by[n].J_u.shape[1], candidate(ctx.d, n).lower / candidate(ctx.d, n).scale) for n in names]
    )
    hi = np.concatenate(
        [np.full(fits_by[n].J_u.shape[1], candidate(ctx.d, n).bound / candidate(ctx.d, n).scale) for n in names]
    )
    return J, lo, hi


def two_dll(ctx: Context, fits_by: dict, names: list, e0: np.ndarray) -> tuple:
    """(2 dLL, rank) of the names' stacked screening Jacobians on e0."""
    if not names:
        return 0.0, 0
    J, lo, hi = stacked(ctx, fits_by, names)
    u = bounded_lstsq(J, -e0, lo, hi)
    r = e0 + J @ u
    return float(e0 @ e0 - r @ r), numerical_rank(J)


def _conditional(ctx, fits_by, names: list, m: str, e0) -> tuple:
    """(-log10 p, rank added, 2 dLL gain) of member m beside the others of names."""
    t, rank = two_dll(ctx, fits_by, names, e0)
    rest = [n for n in names if n != m]
    t0, r0 = two_dll(ctx, fits_by, rest, e0)
    dr = rank - r0
    return (screen_logp(t - t0, dr) if dr > 0 else 0.0), dr, t - t0


def forward_select(ctx: Context, fits: list, threshold_logp: float, max_effects: int = MAX_EFFECTS) -> list:
    """[{"effect", "conditional_logp", "rank_added", "two_dll_gain"}]: the
    chosen set, each member's statistic beside all the others.

    Stepwise: after each addition, a member that no longer passes the
    threshold beside the others is dropped (the weakest first). A candidate
    that absorbs part of two effects is often the first chosen, and the
    right ones, once in, leave it nothing to explain."""
    fits_by = {f.name: f for f in fits if getattr(f, "J_u", None) is not None and np.isfinite(f.screen_bic)}
    e0, _ = training_residuals(ctx)
    chosen, dropped = [], set()
    for _ in range(4 * max_effects):  # bounded: each pass adds one or drops one
        base, base_rank = two_dll(ctx, fits_by, chosen, e0)
        best = None
        if len(chosen) < max_effects:
            for n in fits_by:
                if n in chosen or n in dropped:
                    continue
                t, rank = two_dll(ctx, fits_by, chosen + [n], e0)
                dr = rank - base_rank
                if dr <= 0:
                    continue
                lp = screen_logp(t - base, dr)
                if best is None or lp > best[1]:
                    best = (n, lp)
        if best is None or not best[1] > threshold_logp:
            break
        chosen.append(best[0])
        while len(chosen) > 1:
            cond = {m: _conditional(ctx, fits_by, chosen, m, e0)[0] for m in chosen}
            weakest = min(cond, key=cond.get)
            if cond[weakest] > threshold_logp:
                break
            chosen.remove(weakest)
            dropped.add(weakest)
    steps = []
    for m in chosen:
        lp, dr, gain = _conditional(ctx, fits_by, chosen, m, e0)
        steps.append({"effect": m, "conditional_logp": lp, "rank_added": dr, "two_dll_gain": gain})
    return steps


def confirm_set(ctx: Context, names: list, fits: list, max_nfev: int = 12) -> SetFit:
    """Joint refit of ``names`` with the full filter on the training rows
    (_solve: as one dynamics-only candidate alone when every member is)."""
    d, nominal = ctx.d, ctx.nominal
    fits_by = {f.name: f for f in fits}
    cands = [candidate(d, n) for n in names]
    sizes = [c.n_params for c in cands]
    sc = np.concatenate([np.full(c.n_params, c.scale) for c in cands])
    lb = np.concatenate([np.full(c.n_params, c.lower / c.scale) for c in cands])
    ub = np.concatenate([np.full(c.n_params, c.bound / c.scale) for c in cands])
    e_dyn0 = ctx.ch.e0 if ctx.ch is not None else None
    any_nav = any(c.nav for c in cands)
    rows_ok = np.isfinite(nominal.white[ctx.train_nav]).all(axis=1)

    def split(theta):
        out, i = {}, 0
        for n, k in zip(names, sizes):
            out[n] = theta[i : i + k]
            i += k
        return out

    def dyn_after(theta):
        # Every member applied at once, exactly (bench/gap/dyn.py).
        return None if e_dyn0 is None else ctx.ch.residual(split(theta))

    def corr(theta):
        from bench.gap.replay import Corrections

        c = Corrections()
        for cand, th in zip(cands, split(theta).values()):
            c = c.add(cand.corrections(th, d))
        return c

    def resid(u):
        th = u * sc
        parts = []
        if any_nav:
            w = run_pass(d, corr(th)).white[ctx.train_nav][rows_ok].ravel()
            parts.append(np.nan_to_num(w, nan=1e3))
        else:
            parts.append(nominal.white[ctx.train_nav][rows_ok].ravel())
        if e_dyn0 is not None:
            parts.append(dyn_after(th)[ctx.train_dyn].ravel())
        return np.concatenate(parts)

    u0 = np.clip(np.nan_to_num(np.concatenate([fits_by[n].theta for n in names]) / sc), 0.999 * lb, 0.999 * ub)
    sol = _solve(ctx, names, resid, lambda u: dyn_after(u * sc)[ctx.train_dyn].ravel(), u0, (lb, ub), sc, max_nfev)
    theta = sol.x * sc
    sigma = fit_sigma(sol.jac, sol.x, lb, ub) * sc
    after = run_pass(d, corr(theta)) if any_nav else nominal
    dll = float(np.nansum(after.loglik[ctx.train_nav]) - np.nansum(nominal.loglik[ctx.train_nav]))
    ad = dyn_after(theta)
    if ad is not None:
        e0 = e_dyn0[ctx.train_dyn].ravel()
        e1 = ad[ctx.train_dyn].ravel()
        dll += 0.5 * float(e0 @ e0 - e1 @ e1)
    sf = SetFit(list(names), split(theta), split(sigma), after, ad, dll)
    sf._corr, sf._dyn_after, sf._theta_vec = corr, dyn_after, theta
    return sf


def _solve(ctx: Context, names: list, resid, dyn_resid, u0, bounds: tuple, sc, max_nfev: int):
    """The bounded least-squares solution (``x``, ``jac``) of a set's joint
    refit, in units of each member's scale ``sc``: ``resid`` gives the
    training rows of both channels, ``dyn_resid`` those of the dynamics
    channel.

    A set of dynamics-only members (no navigation signature: a thrust loss,
    a nozzle tilt, a centre-of-mass offset, a mass flow) is refitted as one
    such candidate alone is (attribute.confirm): by chord steps with the
    members' exact Jacobians at the nominal model, directions the data do
    not see (a nozzle turned about its own thrust axis) kept where they
    start. Refitted by finite-difference least squares instead, a nozzle
    tilt drifted along those directions (to the 0.5 rad bound on the bundled
    log), and the pseudo-inverse read the differences' residue there (singular
    values 4e-9 to 8e-7 of the largest, where the exact Jacobian has rounding)
    as sigmas of up to 1.1e5 rad, though refits to redrawn noise moved each
    angle by 0.005 to 0.08 rad: one effect had sigmas of 6e-4 to 0.03 rad
    ranked alone and of 0.024 to 1.1e5 rad as a one-member set (a 12 kg log
    with a hinged panel). A set with a navigation member is refitted by
    least squares on full replays, as before."""
    from scipy.optimize import least_squares

    any_nav = any(candidate(ctx.d, n).nav for n in names)
    Jd = None if any_nav else _dyn_jacobian(ctx, names)
    if Jd is not None:
        return chord_fit(dyn_resid, Jd * sc, u0, *bounds)
    n_max = max_nfev * (u0.size + 1) if any_nav else None
    return least_squares(resid, u0, method="trf", bounds=bounds, max_nfev=n_max, diff_step=1e-3)


def _dyn_jacobian(ctx: Context, names: list):
    """The members' exact Jacobians of the dynamics channel on its training
    rows, side by side (per unit of each parameter), or None when a member
    has none (or the log no dynamics channel)."""
    if ctx.ch is None:
        return None
    cols = []
    for n in names:
        J = ctx.ch.jacobian(n)
        if J is None:
            return None
        cols.append(J[ctx.train_dyn].reshape(-1, J.shape[2]))
    return np.hstack(cols)


def without(sf: SetFit, ctx: Context, name: str):
    """(after_nav, after_dyn) of the joint fit with ``name``'s parameters at zero."""
    th = np.concatenate([np.zeros_like(sf.theta[n]) if n == name else sf.theta[n] for n in sf.names])
    any_nav = any(candidate(ctx.d, n).nav for n in sf.names)
    nav = run_pass(ctx.d, sf._corr(th)) if any_nav else ctx.nominal
    return nav, sf._dyn_after(th)


def as_fit(sf: SetFit) -> Fit:
    """The joint fit in the single-candidate form the report reads."""
    f = Fit(
        "+".join(sf.names),
        "set",
        np.concatenate([sf.theta[n] for n in sf.names]),
        np.concatenate([sf.sigma[n] for n in sf.names]),
        0.0,
        0.0,
    )
    f.after_nav, f.after_dyn, f.dll_train, f.confirmed = sf.after_nav, sf.after_dyn, sf.dll_train, True
    return f
