"""Which in-library effect explains the gap.

Two channels of whitened residuals, each N(0, 1) per element under the
nominal model: the navigation replay's pose innovations (bench/gap/replay.py)
and the dynamics channel, IMU against the valve model (bench/gap/dyn.py).

1. Screen (cheap, every candidate): the candidate's signature is its
   Jacobian on both channels: by finite differences through the filter (one
   replay per parameter) and in closed form on the dynamics channel. A
   linearised generalised likelihood ratio on the training rows,
       theta_hat = argmin |e0 + J theta|^2 (inside the plausible bounds),
       2 dLL = |e0|^2 - |e0 + J theta_hat|^2,
   ordered by the p-value of 2 dLL against chi2(rank) (whose smallest value
   over the candidates is also the detection statistic).
2. Confirm (the top few): refit with the full filter (scipy least_squares,
   every residual evaluation a full replay), then the exact training
   log-likelihood gain and the Bayes factor against the nominal model
   (Laplace's approximation, each parameter with a Cauchy prior at its
   typical size), by which the confirmed candidates are ranked.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.gap.candidates import CANDIDATES, Candidate, candidates_of
from bench.gap.load import LogData
from bench.gap.replay import replay

BF_AMBIGUOUS = float(np.log(20.0))  # ln Bayes factor below which two candidates are not told apart
# Two signatures closer than this (in noise variances) are told apart with
# less than 95 % probability: a one-sided 5 % test either way.
DELTA2_95 = float((2 * 1.6448536269514722) ** 2)  # 10.82


@dataclass
class Pass:
    """One navigation replay, on the full set of pose indices (NaN where not fused)."""

    white: np.ndarray  # (M, 6)
    nis: np.ndarray
    loglik: np.ndarray
    innovation: np.ndarray
    res: object = None


def run_pass(d: LogData, corr=None, keep=False) -> Pass:
    r = replay(d, corr)
    m = d.pose_tc.size
    white = np.full((m, 6), np.nan)
    nis = np.full(m, np.nan)
    ll = np.full(m, np.nan)
    inn = np.full((m, 6), np.nan)
    white[r.index] = r.whitened()
    nis[r.index] = r.nis
    ll[r.index] = r.loglik
    inn[r.index] = r.innovation
    return Pass(white, nis, ll, inn, r if keep else None)


@dataclass
class Context:
    d: LogData
    nominal: Pass
    ch: object  # DynChannel or None
    train_nav: np.ndarray
    held_nav: np.ndarray
    train_dyn: np.ndarray | None
    held_dyn: np.ndarray | None
    split: object = None  # quantify.Split: the blocks, and the valves not fired in both halves


@dataclass
class Fit:
    name: str
    kind: str
    theta: np.ndarray
    sigma: np.ndarray
    screen_2dll: float
    screen_bic: float
    rank: int = 0
    screen_logp: float = 0.0  # -log10 P(chi2_rank > screen_2dll): the detection statistic
    dll_train: float = float("nan")
    bic: float = float("nan")
    ln_bf: float = float("nan")  # ln Bayes factor against the nominal model (Laplace, Cauchy prior at scale)
    screen_ln_bf: float = float("nan")
    bound_excess_sigma: float = 0.0  # unconstrained fit beyond the physical bound [its sigmas]
    confirmed: bool = False
    after_nav: Pass | None = None
    after_dyn: np.ndarray | None = None  # (R, 3) dynamics rows with the candidate


def candidate(d: LogData, name: str) -> Candidate:
    """Candidate ``name`` sized for the log's vehicle (its number of thrusters)."""
    return candidates_of(d)[name]


def _dyn_jac(ctx: Context, name: str):
    if ctx.ch is None:
        return None
    return ctx.ch.jacobian(name)


def training_residuals(ctx: Context, nav: Pass | None = None):
    """The training rows of both channels, whitened, as one vector; and the
    mask of complete navigation rows among the training ones."""
    p = nav if nav is not None else ctx.nominal
    e_nav = p.white[ctx.train_nav]
    rows_ok = np.all(np.isfinite(e_nav), axis=1)
    e_dyn = ctx.ch.e0[ctx.train_dyn].ravel() if ctx.ch is not None else np.zeros(0)
    return np.concatenate([e_nav[rows_ok].ravel(), e_dyn]), rows_ok


def nav_signature(ctx: Context, name: str, progress=None) -> np.ndarray:
    """Candidate ``name``'s Jacobian of the whitened pose innovations on every
    pose update, (M, 6, k): a replay per parameter at its typical size
    (finite differences through the filter); zero where either pass did not
    fuse the update."""
    d = ctx.d
    c = candidate(d, name)
    base = np.nan_to_num(ctx.nominal.white, nan=0.0)
    J = np.zeros(base.shape + (c.n_params,))
    for i in range(c.n_params):
        th = np.zeros(c.n_params)
        th[i] = c.scale
        w = run_pass(d, c.corrections(th, d)).white
        J[:, :, i] = np.where(np.isfinite(ctx.nominal.white), np.nan_to_num(w, nan=0.0) - base, 0.0) / c.scale
        if progress:
            progress()
    return J


def signature(ctx: Context, name: str, rows_ok: np.ndarray, progress=None, given: dict | None = None):
    """Candidate ``name``'s Jacobian on the training rows of both channels
    (through the filter, nav_signature; closed form on the dynamics
    channel), the dynamics one on every row (None without one) and the
    navigation one on every pose update (None for a dynamics-only
    candidate). ``given``: {"nav": ..., "dyn": ...} full Jacobians to use
    instead, each where it has this log's shape."""
    c = candidate(ctx.d, name)
    given = given or {}
    n_nav = int(rows_ok.sum()) * 6
    n_dyn = int(ctx.train_dyn.sum()) * 3 if ctx.ch is not None else 0
    Jn_full = None
    Jn = np.zeros((n_nav, c.n_params))
    if c.nav:
        g = given.get("nav")
        Jn_full = g if g is not None and g.shape == ctx.nominal.white.shape + (c.n_params,) else None
        Jn_full = Jn_full if Jn_full is not None else nav_signature(ctx, name, progress)
        Jn = Jn_full[ctx.train_nav][rows_ok].reshape(n_nav, c.n_params)
    g = given.get("dyn")
    if g is not None and ctx.ch is not None and g.shape == (ctx.ch.rows, 3, c.n_params):
        Jd_full = g
    else:
        Jd_full = _dyn_jac(ctx, name)
    Jd = Jd_full[ctx.train_dyn].reshape(-1, c.n_params) if Jd_full is not None else np.zeros((n_dyn, c.n_params))
    return np.vstack([Jn, Jd]), Jd_full, Jn_full


def signatures(ctx: Context) -> dict:
    """Every candidate's full Jacobians, {name: {"nav", "dyn"}}: what a
    calibration's null runs share with their log (screen's ``given``); each
    only where it reads no measurement (NAV_READINGS_FREE,
    dyn.READINGS_FREE)."""
    from bench.gap.dyn import READINGS_FREE

    rows_ok = np.all(np.isfinite(ctx.nominal.white[ctx.train_nav]), axis=1)
    out = {}
    for name in candidates_of(ctx.d):
        _, jd, jn = signature(ctx, name, rows_ok)
        out[name] = {
            "nav": jn if name in NAV_READINGS_FREE else None,
            "dyn": jd if name in READINGS_FREE else None,
        }
    return out


# Candidates whose navigation Jacobian reads no measurement beyond the
# trajectory (a constant bias, the camera's offset, the orbit's terms): the
# same for every noise draw of one flight. A gyro scale or misalignment
# scales or turns the measured rate, a latency or a clock moves the poses
# along it: their Jacobians carry each draw's noise (dyn.READINGS_FREE).
NAV_READINGS_FREE = (
    "accel_bias",
    "gyro_bias",
    "camera_lever_arm",
    "host_eccentricity",
    "differential_j2",
    "differential_drag",
)


def ln_bayes_factor(
    two_dll: float, u: np.ndarray, Ju: np.ndarray | None, nonnegative: bool = False, F: np.ndarray | None = None
) -> float:
    """ln Bayes factor of a candidate against the nominal model by Laplace's
    approximation at the fit. Parameters in units of the candidate's typical
    size (Candidate.scale), each with a Cauchy prior of unit scale: heavy
    tails, so an effect ten times its typical size costs ln(101) = 4.6 nats,
    not the 50 a Gaussian prior would charge. ``Ju``: the whitened residuals'
    Jacobian in those units; the posterior precision is taken as
    Ju^T Ju + I (the data plus the prior's scale), so a direction the data
    do not pin down is neither charged nor rewarded for fitting noise.

        ln BF = dLL + sum_i ln p(u_i) + k/2 ln(2 pi) - 1/2 ln det(Ju^T Ju + I),
        ln p(u) = -ln(pi) - ln(1 + u^2).

    A candidate whose parameters are non-negative by definition has a
    half-Cauchy prior (twice the density on half the line, + ln 2 each), and
    a parameter held at zero by that bound keeps only the half of its
    Gaussian posterior that lies inside (- ln 2 each). ``F``: Ju^T Ju, when
    already at hand.
    """
    k = u.size
    F = Ju.T @ Ju if F is None else F
    _, logdet = np.linalg.slogdet(np.eye(k) + F)
    ln_prior = float(np.sum(-np.log(np.pi) - np.log1p(u**2)))
    if nonnegative:
        ln_prior += (k - int(np.sum(u <= 0.0))) * float(np.log(2.0))
    return float(0.5 * two_dll + ln_prior + 0.5 * k * np.log(2 * np.pi) - 0.5 * logdet)


def bounded_fit(J: np.ndarray, s: np.ndarray, lower, upper) -> np.ndarray:
    """J theta* with theta* = argmin |s - J theta|^2 over lower <= theta <= upper:
    the part of ``s`` a candidate with those physical bounds can reproduce.
    ``lower``, ``upper``: one bound for every parameter, or one per column
    (several candidates' Jacobians stacked side by side).
    Unbounded (or bounds the fit stays inside): the projection onto J's
    range."""
    U, sv, _ = np.linalg.svd(J, full_matrices=False)
    U = U[:, sv > sv[0] * 1e-9] if sv.size and sv[0] > 0 else U[:, :0]
    p = U @ (U.T @ s)
    lower = np.broadcast_to(np.asarray(lower, float), J.shape[1:])
    upper = np.broadcast_to(np.asarray(upper, float), J.shape[1:])
    if np.all(np.isneginf(lower)) and np.all(np.isposinf(upper)):
        return p
    th, *_ = np.linalg.lstsq(J, p, rcond=None)
    if np.all(th >= lower) and np.all(th <= upper):
        return p
    from scipy.optimize import lsq_linear

    # Columns scaled to unit norm (a whitened signature per unit of a loss is
    # thousands), bounds with them; BVLS is an exact active-set solver.
    norm = np.linalg.norm(J, axis=0)
    keep = norm > 0
    Js = J[:, keep] / norm[keep]
    x = lsq_linear(Js, s, bounds=(lower[keep] * norm[keep], upper[keep] * norm[keep]), method="bvls").x
    return Js @ x


def screen_logp(two_dll: float, rank: int) -> float:
    """-log10 of the GLR's p-value against chi2(rank): comparable across
    candidates of different sizes, unlike BIC (whose ln n per parameter makes
    a 16-parameter candidate need 16 ln n before it counts)."""
    from scipy.stats import chi2

    return float(-chi2.logsf(max(two_dll, 0.0), rank) / np.log(10.0))


def bound_excess(theta_free: np.ndarray, sigma: np.ndarray, bound: float, lower: float | None = None) -> float:
    """How far the unconstrained fit lies beyond the candidate's physical
    bounds [lower, bound] (lower = -bound unless given), in its own standard
    deviations (largest over the parameters; 0 inside). A candidate whose
    data want a physically impossible size is no explanation, however well
    its bounded fit does."""
    lower = -bound if lower is None else lower
    if not np.isfinite(bound) and not np.isfinite(lower):
        return 0.0
    over = np.maximum(theta_free - bound, lower - theta_free)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = over / sigma
    z = np.where(np.isfinite(z), z, np.where(over > 0, np.inf, 0.0))
    return float(max(np.max(z, initial=0.0), 0.0))


# A fitted parameter this close to a physical bound, in units of its
# candidate's typical size (Candidate.scale), is held there by the bound: a
# bounded solver stops on it or, keeping its steps strictly feasible, within
# about 1e-10 of it (a loss of 4e-15, a gyro scale of -0.49999999975 against
# -0.5).
BOUND_TOL = 1e-6


def at_bounds(u, lower, upper) -> np.ndarray:
    """-1 where a fitted parameter is held at its lower bound, +1 at its upper,
    0 inside: ``u``, ``lower``, ``upper`` in units of the candidate's scale
    (one bound for every parameter, or one each), within BOUND_TOL."""
    u = np.asarray(u, float)
    lo = np.broadcast_to(np.asarray(lower, float), u.shape)
    hi = np.broadcast_to(np.asarray(upper, float), u.shape)
    out = np.zeros(u.shape, int)
    out[np.isfinite(lo) & (u - lo <= BOUND_TOL)] = -1
    out[np.isfinite(hi) & (hi - u <= BOUND_TOL)] = 1
    return out


def fit_sigma(J: np.ndarray, u: np.ndarray, lower, upper) -> np.ndarray:
    """1-sigma of each parameter of a bounded least-squares fit at ``u`` (units
    of u), ``J`` the whitened residuals' Jacobian there (or its triangle R,
    R^T R = J^T J). The free parameters' covariance comes from their own
    columns, (J_F^T J_F)^+: the fit holds the ones at a bound (at_bounds)
    fixed there, and their columns would otherwise spread their correlation
    into the free ones (the bundled log's loss of valve 4, held at 0 and
    fired in a couple with valve 0: valve 3's sigma 0.0106 from every
    column, 0.0063 from the free ones, 0.0070 the spread of bounded refits
    of the linearised fit to redrawn noise).
    A parameter at a bound has no sampling sigma; it gets the one the full
    Jacobian gives it, kept only to tell one the data do not narrow (beyond
    its bound, verdict.parameters) or do not see (zero) from one held there,
    never to be shown."""
    J = np.asarray(J, float)
    full = np.sqrt(np.clip(np.diag(np.linalg.pinv(J.T @ J)), 0, None))
    free = at_bounds(u, lower, upper) == 0
    if free.all() or not free.any():
        return full
    Jf = J[:, free]
    out = full.copy()
    out[free] = np.sqrt(np.clip(np.diag(np.linalg.pinv(Jf.T @ Jf)), 0, None))
    return out


def numerical_rank(J: np.ndarray) -> int:
    return int(np.linalg.matrix_rank(J / (np.linalg.norm(J, axis=0) + 1e-300)))


def _screen_fit(c: Candidate, J: np.ndarray, e0: np.ndarray) -> tuple:
    """(theta, sigma, 2 dLL, rank, beyond, R) of the linearised GLR of one
    candidate, solved on the k x k triangle of J's QR decomposition (the
    rows are tens of thousands, the parameters few): |e0 + J u|^2 =
    |Q^T e0 + R u|^2 + what no u reaches, with J's own conditioning."""
    k = J.shape[1]
    from scipy.linalg import qr

    (Ra,) = qr(np.column_stack([J, -e0]), mode="r", check_finite=False)  # [R, Q^T (-e0)]: Q never formed
    R, y = np.triu(Ra[:k, :k]), Ra[:k, k]
    rank = numerical_rank(R)  # R's columns have J's norms and J's singular values
    if rank == 0:
        return None
    rcond = np.finfo(float).eps * max(J.shape)
    u = np.linalg.lstsq(R, y, rcond=rcond)[0]
    sig = np.sqrt(np.clip(np.diag(np.linalg.pinv(R.T @ R)), 0, None))
    beyond = bound_excess(u, sig, c.bound, c.lower)
    if np.any(u > c.bound) or np.any(u < c.lower):
        from scipy.optimize import lsq_linear

        u = lsq_linear(R, y, bounds=(c.lower, c.bound)).x
    r = R @ u - y
    two_dll = float(y @ y - r @ r)  # |e0|^2 - |e0 + J u|^2
    return u, sig, two_dll, rank, beyond, R


def screen(ctx: Context, names=None, progress=None, given: dict | None = None) -> list:
    """The linearised GLR fit of every candidate (or of ``names``) on the
    training rows, best first. ``given``: full Jacobians by candidate
    (signatures()) used instead of computing them, where they have the
    log's shape: the null runs of a calibration share their log's (the same
    flight, plan and time stamps, only the noise differs; the statistics
    move by a few hundredths)."""
    e0, rows_ok = training_residuals(ctx)
    n_obs = e0.size
    fits = []
    for name in names or CANDIDATES:
        c = candidate(ctx.d, name)
        J, Jd_full, Jn_full = signature(ctx, name, rows_ok, progress, (given or {}).get(name))
        fit = _screen_fit(c, J, e0)
        if fit is None:
            fits.append(Fit(name, c.kind, np.zeros(c.n_params), np.full(c.n_params, np.nan), 0.0, -np.inf, 0))
            continue
        u, sig, two_dll, rank, beyond, R = fit
        f = Fit(name, c.kind, u, sig, two_dll, two_dll - rank * np.log(n_obs), rank, screen_logp(two_dll, rank))
        f.bound_excess_sigma = beyond
        f.J_u = J * c.scale
        f.screen_ln_bf = ln_bayes_factor(two_dll, u / c.scale, R * c.scale, c.nonnegative)
        f.Jd_full = Jd_full
        f.Jn_full = Jn_full
        fits.append(f)
    # Screening order: the GLR's p-value (the detection statistic), which
    # compares candidates of different sizes fairly; the confirmed ones are
    # then ranked by their Bayes factors.
    fits.sort(key=lambda f: -f.screen_logp)
    return fits


def chord_fit(resid, J: np.ndarray, u0: np.ndarray, lb, ub, max_iter: int = 30, tol: float = 1e-8):
    """Bounded least squares of a mildly nonlinear residual by chord steps:
    each step the minimum-norm solution of the linear problem with the fixed
    Jacobian ``J`` (its QR triangle: k rows) from the residual where it
    stands, inside the bounds (exactly where every direction is seen; a
    loss stays >= 0). Minimum norm where some are not: directions the data
    do not see (a nozzle turned about its own thrust axis) stay where they
    start instead of wandering to a bound; where that step would cross a
    bound (a loss beside a nozzle tilt, select.confirm_set), the bounded step
    with those directions held by a penalty as stiff as the best-seen
    direction (clipped, the bundled log's loss and tilt stopped at a
    training log-likelihood gain of 2223, below the loss's 2846 alone; 2854
    bounded). Returns an object with ``x`` and ``jac`` (the k x k
    triangle, whose R^T R is J^T J)."""
    from types import SimpleNamespace

    from scipy.linalg import qr
    from scipy.optimize import lsq_linear

    Q, R = qr(J, mode="economic", check_finite=False)
    rcond = 1e-6
    u = np.clip(np.asarray(u0, float).copy(), lb, ub)
    # From the screen's fit, its part the data do not see removed.
    _, sv, vt = np.linalg.svd(R)
    seen = vt[sv > sv[0] * rcond]
    u = np.clip(seen.T @ (seen @ u), lb, ub)
    full = seen.shape[0] == u.size
    # A step along what the data do not see costs as much as along what they see best.
    hold = vt[sv <= sv[0] * rcond] * sv[0]
    for _ in range(max_iter):
        y = -(Q.T @ resid(u))
        if full:  # every direction seen: the bounded step exactly (a loss is >= 0)
            step = lsq_linear(R, y, bounds=(lb - u, ub - u)).x
        else:
            step = np.linalg.lstsq(R, y, rcond=rcond)[0]
            if np.any(u + step < lb) or np.any(u + step > ub):
                # A bound in the way (a loss beside a nozzle tilt): the bounded
                # step, what the data do not see held where it is.
                A, b = np.vstack([R, hold]), np.concatenate([y, np.zeros(hold.shape[0])])
                step = lsq_linear(A, b, bounds=(lb - u, ub - u)).x
        new = np.clip(u + step, lb, ub)
        done = np.linalg.norm(new - u) <= tol * (1.0 + np.linalg.norm(u))
        u = new
        if done:
            break
    return SimpleNamespace(x=u, jac=R)


def confirm(ctx: Context, fit: Fit, max_nfev: int = 12) -> Fit:
    """Refit with the full filter likelihood on the training rows (both
    channels; the dynamics channel with the candidate applied exactly)."""
    from scipy.optimize import least_squares

    d, nominal, ch = ctx.d, ctx.nominal, ctx.ch
    c: Candidate = candidate(d, fit.name)
    has_dyn = ch is not None and ch.jacobian(fit.name) is not None

    def dyn_after(theta):
        if ch is None:
            return None
        return ch.residual({fit.name: theta}) if has_dyn else ch.e0

    sc = np.full(c.n_params, c.scale)
    ub, lb = c.bound / c.scale, c.lower / c.scale
    u0 = np.clip(np.nan_to_num(fit.theta / sc), 0.999 * lb, 0.999 * ub)
    if c.nav:
        rows_ok = np.isfinite(nominal.white[ctx.train_nav]).all(axis=1)

        def resid(u):
            w = run_pass(d, c.corrections(u * sc, d)).white[ctx.train_nav][rows_ok].ravel()
            parts = [np.nan_to_num(w, nan=1e3)]
            if has_dyn:
                parts.append(dyn_after(u * sc)[ctx.train_dyn].ravel())
            return np.concatenate(parts)

        kw = dict(max_nfev=max_nfev * (c.n_params + 1), diff_step=1e-3)
        sol = (
            least_squares(resid, u0, method="trf", bounds=(lb, ub), **kw)
            if np.isfinite(ub)
            else least_squares(resid, u0, method="lm", **kw)
        )
        theta = sol.x * sc
        J_u = sol.jac
        sigma = fit_sigma(sol.jac, sol.x, lb, ub) * sc
        after = run_pass(d, c.corrections(theta, d))
        dll = float(np.nansum(after.loglik[ctx.train_nav]) - np.nansum(nominal.loglik[ctx.train_nav]))
    elif has_dyn:
        # Dynamics only: the exact channel is cheap, so the fit is refined on it
        # from the screen's linearised one (a tilt is a rotation, a mass flow
        # divides, a sensor error enters the gyroscopic term), by chord steps
        # with the Jacobian at the nominal model (a tilt has 3 parameters per
        # valve: a finite difference per parameter per step cost 10 s).
        sol = chord_fit(
            lambda u: dyn_after(u * sc)[ctx.train_dyn].ravel(),
            ch.jacobian(fit.name)[ctx.train_dyn].reshape(-1, c.n_params) * sc,
            u0,
            lb,
            ub,
        )
        theta, J_u = sol.x * sc, sol.jac
        sigma = fit_sigma(sol.jac, sol.x, lb, ub) * sc
        after, dll = nominal, 0.0
    else:
        theta, sigma, after, dll = fit.theta, fit.sigma, nominal, 0.0
        J_u = getattr(fit, "J_u", np.zeros((0, c.n_params)))
    ad = dyn_after(theta)
    if ad is not None:
        e0 = ch.e0[ctx.train_dyn].ravel()
        e1 = ad[ctx.train_dyn].ravel()
        dll += 0.5 * float(e0 @ e0 - e1 @ e1)
    n_obs = int(np.isfinite(nominal.white[ctx.train_nav]).all(axis=1).sum()) * 6 + (
        int(ctx.train_dyn.sum()) * 3 if ctx.ch is not None else 0
    )
    fit.theta, fit.sigma, fit.dll_train = theta, sigma, dll
    fit.bic = 2 * dll - max(fit.rank, 1) * np.log(max(n_obs, 2))
    fit.ln_bf = ln_bayes_factor(2 * dll, theta / c.scale, J_u, c.nonnegative)
    fit.confirmed = True
    fit.after_nav, fit.after_dyn = after, ad
    return fit
