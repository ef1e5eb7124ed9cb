"""Modal-estimator campaigns: the paper's simulation (plate) and experiment
(quadruple pendulum), run through the flight code (fsw_bindings).

Per image: the estimator's mode shapes at the measured points -> flight
decomposition (eqs. 2-4) -> flight filter step (bank or joint, eqs. 5-7) ->
shape reconstruction (eqs. 8-9) for the shape error.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np

from bench.sim import structure as st


def _fb():
    import fsw_bindings as fb

    return fb


def make_filter(kind, m, omega, alpha, sigma_v0, sigma_w0, sigma_a0, q_a, q_v, q_w=None, q_al=None, ut_alpha=1.0):
    fb = _fb()
    cls = getattr(fb, ("ModalUkfBank" if kind == "bank" else "ModalUkfJoint") + str(m))
    z = np.zeros(m)
    return cls(
        omega_radps=np.asarray(omega, float),
        alpha_ps=np.asarray(alpha, float),
        sigma_v0_ps=np.broadcast_to(np.asarray(sigma_v0, float), (m,)).copy(),
        sigma_omega0_radps=np.broadcast_to(np.asarray(sigma_w0, float), (m,)).copy(),
        sigma_alpha0_ps=np.broadcast_to(np.asarray(sigma_a0, float), (m,)).copy(),
        q_a=np.broadcast_to(np.asarray(q_a, float), (m,)).copy(),
        q_v=np.broadcast_to(np.asarray(q_v, float), (m,)).copy(),
        q_omega=z if q_w is None else np.broadcast_to(np.asarray(q_w, float), (m,)).copy(),
        q_alpha=z if q_al is None else np.broadcast_to(np.asarray(q_al, float), (m,)).copy(),
        ut_alpha=float(ut_alpha),
    )


def _converged_index(est, truth, rel=None, abs_=None):
    """First index from which every later estimate is within the band (None: never)."""
    est = np.asarray(est, float).reshape(len(est), -1)
    truth = np.asarray(truth, float).reshape(1, -1)
    band = rel * np.abs(truth) if rel is not None else abs_
    bad = np.nonzero(np.any(np.abs(est - truth) > band, axis=1))[0]
    if bad.size == 0:
        return 0
    k = int(bad[-1]) + 1
    return k if k < est.shape[0] else None


def run_trial(item: dict, spec: dict) -> dict:
    """One trial as a campaign task (bench/runner/runner.py): ``spec`` names
    the scenario and its keyword arguments, ``item`` the trial's seed and
    whether it keeps its series for the plots."""
    fn = pendulum_trial if spec["scenario"] == "pendulum" else plate_trial
    return fn(item["seed"], keep_series=item["keep_series"], **spec["kwargs"])


# ---------------------------------------------------------------------------
# Pendulum (experiment analogue)


def pendulum_trial(
    seed: int,
    kind: str = "bank",
    duration_s: float = 10.0,
    rate_hz: float = 15.0,
    n_points: int = 600,
    noise_m: float = 0.003,
    keep_series: bool = False,
):
    fb = _fb()
    rng = np.random.default_rng(seed)
    pend = st.Pendulum()
    m = 3
    amp = np.array([0.05, 0.03, 0.03]) * rng.uniform(0.7, 1.0, m)
    phase = rng.uniform(0, 2 * np.pi, m)
    th_est = pend.estimator_modes(rng, n_modes=m)
    w0 = st.PENDULUM_OMEGA_PRIOR
    filt = make_filter(
        kind,
        m,
        w0,
        st.PENDULUM_ALPHA_PRIOR,
        sigma_v0=w0 * 0.05,
        sigma_w0=0.1 * w0,
        sigma_a0=[0.1, 0.1, 1.0],
        q_a=1e-9,
        q_v=1e-7,
    )
    dec = fb.ModalDecomposition3(sigma_e_m=noise_m)
    dt = 1.0 / rate_hz
    steps = int(round(duration_s * rate_hz))
    est = np.zeros((steps, m, 4))
    coarse = np.full((steps, m), np.nan)
    truth = np.zeros((steps, m))
    statuses, n_nan = [], 0
    for k in range(steps):
        t = k * dt
        a = st.pendulum_coeffs(amp, phase, t)
        s, z = st.pendulum_image(pend, a, rng, n_points=n_points, noise_m=noise_m)
        phi = pend.phi(th_est, s)
        rec = dec.decompose(phi, z)
        n_nan += rec.n_nonfinite
        if rec.ok:
            coarse[k] = rec.a_coarse
        r = filt.step(dt, rec)
        statuses.append(r["status"])
        est[k] = filt.state
        truth[k] = a
    w_true, a_true = st.PENDULUM_OMEGA[:2], st.PENDULUM_ALPHA[:2]
    kw = _converged_index(est[:, :2, 2], w_true, rel=0.01)
    ka = _converged_index(est[:, :2, 3], a_true, abs_=0.02)
    n_conv = None if kw is None or ka is None else max(kw, ka) + 1  # measurements, the first included
    out = {
        "seed": seed,
        "omega_final_radps": est[-1, :, 2],
        "alpha_final_ps": est[-1, :, 3],
        "omega_std_radps": filt.state_std[:, 2],
        "alpha_std_ps": filt.state_std[:, 3],
        "measurements_to_converge": n_conv,
        "n_nonfinite_points": n_nan,
        "n_not_ok": int(sum(s != "ok" for s in statuses)),
    }
    if keep_series:
        out.update(t_s=np.arange(steps) * dt, est=est, coarse=coarse, truth=truth)
    return out


# ---------------------------------------------------------------------------
# Plate (simulation)


@dataclass(frozen=True)
class _TrialSetup:
    """What a plate trial's scoring needs beside its flight: image times, the
    true and a priori frequencies, the modes excited enough to be scored."""

    t: np.ndarray  # image times [s]
    dt_s: float
    amp: np.ndarray  # true modal amplitudes
    phase: np.ndarray
    w_true: np.ndarray  # true frequencies [rad/s]
    w_prior: np.ndarray  # a priori frequencies
    sigma_w_prior: np.ndarray  # their 1-sigma
    strong: np.ndarray  # modes excited >= 0.2 (the others' frequencies are not observable)
    period1: float  # the lowest mode's period [s]


def plate_trial(
    seed: int,
    n_modes: int = 10,
    kind: str = "bank",
    n_images: int = 180,
    dt_s: float = 60.0,
    prior_err: float = 0.1,
    noise_frac: float = 0.03,
    keep_series: bool = False,
    oracle: bool = True,
    batch_ml_periods=(),
    crb_periods=(),
    acquire_periods=None,
    acquire_sigma_rel=0.01,
    acquire_with="flight",
    acquire_grid_sigmas=3.0,
    ut_alpha=1.0,
    points_at="measured",
    coarse_check=False,
):
    """One simulation run. prior_err: a priori frequency error, drawn per mode
    uniformly in +-prior_err (the paper assumes it bounded by about 20 %).
    batch_ml_periods: times [lowest-mode periods] at which the batch ML
    reference (bench.campaigns.modal_batch_ml) is fitted to every coarse estimate so far
    and its shape error compared with the filter's at the same image.
    crb_periods: times [lowest-mode periods] at which the Cramer-Rao bounds
    of this run's coarse estimates (bench.campaigns.modal_crb) are set beside the
    filter's frequency and shape errors.
    acquire_periods: frequency acquisition set beside the one-pass filter:
    at that time a search over every image so far gives the frequencies; a
    new flight joint filter from them (1-sigma acquire_sigma_rel of each) is
    replayed over those images and then runs on, scored at the crb_periods
    times. acquire_with "flight": the flight ModalAcquisition (RELAX on its
    stored history, fsw/include/fsw/modal/modal_acquisition.hpp) and its replay;
    "batch-ml": the bench's batch ML fit (bench.campaigns.modal_batch_ml), the
    reference it is compared with. acquire_grid_sigmas: the flight search's
    frequency grid spans +- that many a priori sigmas (sigma 10 % here).
    ut_alpha: the unscented transform's spread parameter of the estimating
    filters (sigma points at ut_alpha sqrt(n) standard deviations).
    points_at: where the estimator evaluates the mode shapes
    (bench.sim.structure.plate_points). coarse_check: also compare every
    image's coarse amplitudes with the truth (normalised estimation error
    squared, per-mode bias in units of the reported sigma)."""
    plate = st.Plate(n_modes=n_modes)
    w1 = plate.omega_radps[0]
    batch_ml_images = _images_at(batch_ml_periods, w1, dt_s, n_images, "batch ML reference")
    crb_images = _images_at(crb_periods, w1, dt_s, n_images, "Cramer-Rao bound")
    new_filter = partial(_plate_filter, kind, n_modes, ut_alpha)
    if acquire_periods is not None:
        if not crb_periods:
            raise ValueError("the two-pass prototype is scored at the Cramer-Rao times: give crb_periods (--crb-at)")
        (acquire_image,) = _images_at([acquire_periods], w1, dt_s, n_images, "acquisition")
    keep_cov = bool(batch_ml_periods or crb_periods or acquire_periods or coarse_check)
    fl = _PlateFlight(plate, n_images, keep_cov, keep_records=acquire_periods is not None)
    su = _fly_plate(fl, plate, seed, dt_s, prior_err, noise_frac, points_at, new_filter, oracle)
    out = _plate_summary(seed, kind, dt_s, su.amp, su.w_true, su.w_prior, fl)
    if oracle:
        out.update(_shape_convergence(fl.shape_rms, fl.shape_rms_oracle, dt_s, su.period1))
    if batch_ml_periods:
        out["batch_ml"] = [_batch_ml_row(k, fl, su) for k in batch_ml_images]
    if crb_periods:
        out["crb"] = [_crb_row(k, fl, su) for k in crb_images]
    if acquire_periods is not None:
        out["acquisition"] = _acquire(
            acquire_with, acquire_image, fl, su, acquire_sigma_rel, new_filter, crb_images, acquire_grid_sigmas
        )
    if coarse_check:
        out["coarse_check"] = _coarse_check(fl.coarse, fl.coarse_cov, fl.truth)
    out["points_at"] = points_at
    if keep_series:
        out.update(t_s=su.t, est=fl.est, coarse=fl.coarse, truth=fl.truth)
    return out


def _fly_plate(fl, plate, seed: int, dt_s, prior_err, noise_frac, points_at, new_filter, oracle: bool) -> _TrialSetup:
    """Draw the trial's truth and a priori frequencies from ``seed`` and fly
    ``fl`` through its images; returns what the scoring needs."""
    rng = np.random.default_rng(seed)
    sensor = st.plate_sensor(plate)
    amp, phase = st.plate_truth(plate, rng)
    w_true = plate.omega_radps
    w_prior = w_true * (1 + rng.uniform(-prior_err, prior_err, plate.n_modes))
    sigma_w_prior = 0.1 * w_prior
    fl.fly(
        sensor,
        amp,
        phase,
        rng,
        dt_s,
        noise_frac,
        points_at,
        new_filter(w_prior, sigma_w_prior),
        new_filter(w_true, 1e-6 * w_true) if oracle else None,
    )
    return _TrialSetup(
        t=np.arange(fl.est.shape[0]) * dt_s,
        dt_s=dt_s,
        amp=amp,
        phase=phase,
        w_true=w_true,
        w_prior=w_prior,
        sigma_w_prior=sigma_w_prior,
        strong=amp >= 0.2,  # see _plate_summary
        period1=2 * np.pi / w_true[0],
    )


def _plate_filter(kind: str, n_modes: int, ut_alpha: float, w0, sw0):
    """The plate's estimating filter from frequencies w0 with 1-sigma sw0."""
    return make_filter(
        kind,
        n_modes,
        w0,
        np.zeros(n_modes),
        sigma_v0=w0 * 1.0,
        sigma_w0=sw0,
        sigma_a0=1e-6,
        q_a=0.0,
        q_v=0.0,
        ut_alpha=ut_alpha,
    )


class _PlateFlight:
    """Per image of a plate run: the decomposition, the filter's state, and
    the shape error on a 40 x 40 grid of the filter (and of the filter that
    knows the frequencies, the oracle)."""

    def __init__(self, plate, n_images: int, keep_cov: bool, keep_records: bool):
        m = plate.n_modes
        self.plate = plate
        gx, gy = plate.grid(40)
        self.phi_grid = plate.phi(gx, gy)
        self.dec = getattr(_fb(), f"ModalDecomposition{m}")()
        self.shape = getattr(_fb(), f"reconstruct_shape{m}")
        self.est = np.zeros((n_images, m, 4))
        self.coarse = np.full((n_images, m), np.nan)
        self.coarse_cov = np.full((n_images, m, m), np.nan) if keep_cov else None
        self.records = [] if keep_records else None
        self.truth = np.zeros((n_images, m))
        self.shape_rms = np.full(n_images, np.nan)
        self.shape_rms_oracle = np.full(n_images, np.nan)
        self.shape_sigma = np.full(n_images, np.nan)
        self.cond, self.n_used, self.n_nan, self.statuses = [], [], [], []

    def fly(self, sensor, amp, phase, rng, dt_s: float, noise_frac: float, points_at: str, filt, orc) -> None:
        plate = self.plate
        for k in range(self.est.shape[0]):
            a = st.plate_coeffs(plate, amp, phase, k * dt_s)
            r_meas, d = st.plate_range_image(plate, sensor, a, rng, noise_frac=noise_frac)
            phi, z, var = st.plate_points(plate, sensor, r_meas, d, noise_frac=noise_frac, at=points_at)
            rec = self.dec.decompose(phi, z, var)
            self.cond.append(rec.condition_number)
            self.n_used.append(rec.n_used)
            self.n_nan.append(rec.n_nonfinite)
            if rec.ok:
                self.coarse[k] = rec.a_coarse
                if self.coarse_cov is not None:
                    self.coarse_cov[k] = rec.cov_a
            self.statuses.append(filt.step(dt_s, rec)["status"])
            if self.records is not None:
                self.records.append(rec)
            self.est[k] = filt.state
            self.truth[k] = a
            z_true = self.phi_grid @ a
            if filt.initialized:
                z_hat, var_hat = self.shape(filt.amplitudes, filt.amplitude_cov, self.phi_grid)
                self.shape_rms[k] = np.sqrt(np.mean((z_hat - z_true) ** 2))
                self.shape_sigma[k] = np.sqrt(np.mean(var_hat))
            if orc is not None:
                orc.step(dt_s, rec)
                if orc.initialized:
                    z_o, _ = self.shape(orc.amplitudes, orc.amplitude_cov, self.phi_grid)
                    self.shape_rms_oracle[k] = np.sqrt(np.mean((z_o - z_true) ** 2))


def _plate_summary(seed: int, kind: str, dt_s: float, amp, w_true, w_prior, fl: _PlateFlight) -> dict:
    """Frequency convergence, final errors and the decomposition's figures."""
    n_modes = w_true.size
    est = fl.est
    period1 = 2 * np.pi / w_true[0]
    kw = _converged_index(est[:, :, 2], w_true, rel=0.01)
    per_mode = [_converged_index(est[:, i, 2], w_true[i], rel=0.01) for i in range(n_modes)]
    # Modes excited to at least 0.2 (of the U[0, 1] range): weaker ones carry
    # too little signal at this noise for their frequency to show in a few periods.
    strong = amp >= 0.2
    ks = [per_mode[i] for i in np.nonzero(strong)[0]]
    k_strong = None if any(v is None for v in ks) else (max(ks) if ks else 0)
    return {
        "seed": seed,
        "n_modes": n_modes,
        "amp_true": amp,
        "mode_converge_index_1pct": per_mode,
        "measurements_to_converge_1pct_excited": k_strong,
        "time_to_converge_1pct_excited_periods": None
        if k_strong is None
        else k_strong * dt_s / (2 * np.pi / w_true[0]),
        "kind": kind,
        "dt_s": dt_s,
        "period1_s": period1,
        "omega_true_radps": w_true,
        "omega_prior_radps": w_prior,
        "omega_final_radps": est[-1, :, 2],
        "freq_rel_err_final_max": float(np.max(np.abs(est[-1, :, 2] / w_true - 1))),
        "measurements_to_converge_1pct": kw,
        "time_to_converge_1pct_periods": None if kw is None else kw * dt_s / period1,
        "shape_rms_m": fl.shape_rms,
        "shape_rms_oracle_m": fl.shape_rms_oracle,
        "shape_sigma_m": fl.shape_sigma,
        "condition_number_median": float(np.median(fl.cond)),
        "n_points_used_median": float(np.median(fl.n_used)),
        "n_nonfinite_median": float(np.median(fl.n_nan)),
        "n_not_ok": int(sum(s != "ok" for s in fl.statuses)),
    }


def _shape_convergence(shape_rms, shape_rms_oracle, dt_s: float, period1: float) -> dict:
    """The oracle's shape error over the second half (the noise floor), and
    the first image from which the filter's 5-image running median stays
    within twice it."""
    n_images = shape_rms.size
    floor = float(np.median(shape_rms_oracle[n_images // 2 :]))
    rm = np.array([np.nanmedian(shape_rms[max(0, i - 2) : i + 3]) for i in range(n_images)])
    bad = np.nonzero(~(rm <= 2.0 * floor))[0]
    ks = 0 if bad.size == 0 else int(bad[-1]) + 1
    return {
        "shape_noise_floor_m": floor,
        "shape_converge_index": ks if ks < n_images else None,
        "shape_converge_periods": None if ks >= n_images else ks * dt_s / period1,
    }


def _coarse_check(coarse, cov, truth):
    """Coarse amplitudes (eq. 3) against the truth, with their covariance
    (eq. 4): NEES e^T C^-1 e per image (chi-square with M dof if eq. 4 is
    right) and e_i / sqrt(C_ii) per mode (zero mean, unit spread)."""
    ok = np.all(np.isfinite(coarse), axis=1)
    e = coarse[ok] - truth[ok]
    c = cov[ok]
    nees = np.einsum("ki,ki->k", e, np.linalg.solve(c, e[:, :, None])[:, :, 0])
    z = e / np.sqrt(np.diagonal(c, axis1=1, axis2=2))
    return {"images": int(ok.sum()), "nees": nees, "z_mean": z.mean(axis=0), "z_sq_sum": np.sum(z**2, axis=0)}


def _acquire(method, k0, fl, su: _TrialSetup, sigma_rel, new_filter, score_images, grid_sigmas=3.0):
    """Frequencies from the first k0 images (method "flight" or "batch-ml"),
    then a flight joint filter from them over every image."""
    import time

    t, w_true, strong, period1 = su.t, su.w_true, su.strong, su.period1
    records, shape, phi_grid, truth = fl.records, fl.shape, fl.phi_grid, fl.truth
    want = {k - 1 for k in score_images}
    rows = []

    def score(filt, k):
        if k in want and filt.initialized:
            z_hat, _ = shape(filt.amplitudes, filt.amplitude_cov, phi_grid)
            rows.append(
                {
                    "images": k + 1,
                    "periods": float(t[k] / period1),
                    "excited_within_1pct": _excited_within_1pct(filt.state[:, 2], w_true, strong),
                    "shape_rms_m": float(np.sqrt(np.mean((z_hat - phi_grid @ truth[k]) ** 2))),
                    "shape_rms_known_omega_m": float(fl.shape_rms_oracle[k]),
                }
            )

    out = {"method": method, "images": int(k0), "periods": float(t[k0 - 1] / period1), "sigma_rel": sigma_rel}
    if method == "flight":
        out["grid_sigmas"] = grid_sigmas
        acq = getattr(_fb(), f"ModalAcquisition{len(su.w_prior)}")(
            su.w_prior, su.sigma_w_prior, grid_sigmas=grid_sigmas
        )
        stored = [k for k in range(k0) if records[k].ok and acq.add(float(t[k]), records[k]) == "ok"]
        t0 = time.perf_counter()
        status = acq.search()
        out["search_s"] = time.perf_counter() - t0
        if status != "ok":
            raise RuntimeError(f"frequency acquisition at image {k0}: {status}")
        omega = acq.omega
        filt = new_filter(omega, sigma_rel * omega)
        t0 = time.perf_counter()
        out["replay_fused"] = acq.replay_into(filt)
        out["replay_s"] = time.perf_counter() - t0
        if stored[-1] < k0 - 1:  # the replay ends at the last stored image: on to the acquisition's time
            filt.predict(float(t[k0 - 1] - t[stored[-1]]))
        score(filt, k0 - 1)
    elif method == "batch-ml":
        from bench.campaigns import modal_batch_ml

        if grid_sigmas != 3.0:
            raise ValueError("the batch ML searches +-3 sigma: acquire_grid_sigmas applies to the flight search only")
        ml = modal_batch_ml.fit(fl.coarse[:k0], fl.coarse_cov[:k0], t[:k0], su.w_prior, su.sigma_w_prior)
        out["batch_ml_start"] = ml["start"]
        omega = ml["omega"]
        filt = new_filter(omega, sigma_rel * omega)
        for k in range(k0):
            filt.step(su.dt_s, records[k])
        score(filt, k0 - 1)
    else:
        raise ValueError(f"acquire_with: 'flight' or 'batch-ml', got {method!r}")
    for k in range(k0, len(records)):  # on from the acquisition, live; scored at times before it: nothing
        filt.step(su.dt_s, records[k])
        score(filt, k)
    out["omega_radps"] = np.asarray(omega, float)
    out["search_excited_within_1pct"] = _excited_within_1pct(omega, w_true, strong)
    out["at"] = rows
    return out


def _excited_within_1pct(omega, w_true, strong):
    """How many modes excited >= 0.2 have their frequency within 1 %."""
    return int(np.sum(np.abs(np.asarray(omega) / w_true - 1)[strong] <= 0.01))


def _images_at(periods, omega1, dt_s, n_images, what):
    """Image counts that reach the given times [lowest-mode periods]."""
    images = [int(round(p * 2 * np.pi / omega1 / dt_s)) + 1 for p in periods]
    for p, k in zip(periods, images):
        if not 3 <= k <= n_images:
            raise ValueError(f"{what} at {p} lowest-mode periods needs {k} images; the run has {n_images}")
    return images


def _crb_row(k, fl, su: _TrialSetup):
    """The Cramer-Rao bounds of the first k images beside the filter at image k - 1."""
    from bench.campaigns import modal_crb

    t, w_true, strong, est, cov = su.t, su.w_true, su.strong, fl.est, fl.coarse_cov
    ok = np.all(np.isfinite(cov[:k]), axis=(1, 2))
    # a = amp sin(w t + phase) = c cos(w t) + s sin(w t)
    b = modal_crb.bound(
        t[:k][ok],
        w_true,
        su.amp * np.sin(su.phase),
        su.amp * np.cos(su.phase),
        cov[:k][ok],
        su.sigma_w_prior,
        fl.phi_grid,
        strong=strong,
    )
    rel = np.abs(est[k - 1, :, 2] / w_true - 1)
    return {
        "images": int(k),
        "periods": float(t[k - 1] / su.period1),
        "crb_sd_omega_rel": b["sd_omega_rel"],
        "crb_p_within_1pct": b["p_within_band"],
        "crb_expected_excited_within_1pct": b["expected_within_band_scored"],
        "crb_p_all_excited_within_1pct": b["p_all_scored_within_band"],
        "n_excited": b["n_scored"],
        "filter_excited_within_1pct": _excited_within_1pct(est[k - 1, :, 2], w_true, strong),
        "filter_freq_rel_err": rel,
        "crb_shape_rms_m": b["shape_rms_bound_m"],
        "crb_shape_rms_known_omega_m": b["shape_rms_bound_known_omega_m"],
        "shape_rms_filter_m": float(fl.shape_rms[k - 1]),
        "shape_rms_known_omega_m": float(fl.shape_rms_oracle[k - 1]),
    }


def _batch_ml_row(k, fl, su: _TrialSetup):
    """The batch ML reference on the first k images beside the filter at image k - 1."""
    from bench.campaigns import modal_batch_ml

    t, w_true, strong, est, truth, phi_grid = su.t, su.w_true, su.strong, fl.est, fl.truth, fl.phi_grid
    ml = modal_batch_ml.fit(
        fl.coarse[:k],
        fl.coarse_cov[:k],
        t[:k],
        su.w_prior,
        su.sigma_w_prior,
        extra_starts=[("filter", est[k - 1, :, 2])],
        reference_starts=[("truth", w_true)],
    )
    err = phi_grid @ (ml["amplitude_end"] - truth[k - 1])
    ref = ml["reference"]["truth"]
    err_ref = phi_grid @ (ref["amplitude_end"] - truth[k - 1])

    return {
        "images": int(k),
        "periods": float(t[k - 1] / su.period1),
        "shape_rms_batch_ml_m": float(np.sqrt(np.mean(err**2))),
        "shape_rms_filter_m": float(fl.shape_rms[k - 1]),
        "shape_rms_known_omega_m": float(fl.shape_rms_oracle[k - 1]),
        "omega_batch_ml_radps": ml["omega"],
        # over the modes excited >= 0.2 (the others' frequencies are not observable yet)
        "freq_rel_err_max_excited_batch_ml": float(np.max(np.abs(ml["omega"] / w_true - 1)[strong], initial=0.0)),
        "freq_rel_err_max_excited_filter": float(np.max(np.abs(est[k - 1, :, 2] / w_true - 1)[strong], initial=0.0)),
        "excited_within_1pct_batch_ml": _excited_within_1pct(ml["omega"], w_true, strong),
        "excited_within_1pct_filter": _excited_within_1pct(est[k - 1, :, 2], w_true, strong),
        "n_excited": int(np.sum(strong)),
        "batch_ml_start": ml["start"],
        "batch_ml_cost": ml["cost"],
        # the optimum reached from the true frequencies (not an estimator: it tells whether the
        # data hold a better optimum near the truth than the estimator's starts found)
        "from_truth_cost": ref["cost"],
        "from_truth_excited_within_1pct": _excited_within_1pct(ref["omega"], w_true, strong),
        "shape_rms_from_truth_m": float(np.sqrt(np.mean(err_ref**2))),
    }


def plate_aliased_case(n_modes: int = 10):
    """The ill-conditioned cases, reported by the flight decomposition:
    (a) fewer points than modes, (b) points only on the diagonal x/Lx = y/Ly
    of a square plate, where modes (p, q) and (q, p) coincide (aliased)."""
    fb = _fb()
    dec = getattr(fb, f"ModalDecomposition{n_modes}")()
    plate = st.Plate(n_modes=n_modes)
    x = np.linspace(10, plate.lx_m - 10, n_modes - 1)
    few = dec.decompose(plate.phi(x, x * plate.ly_m / plate.lx_m), np.zeros(x.size))
    sq = st.Plate(n_modes=n_modes, ly_m=2000.0)
    x = np.linspace(10, sq.lx_m - 10, 500)
    alias = dec.decompose(sq.phi(x, x), np.zeros(x.size))
    return {
        "too_few_points": {"status": few.status, "n_used": few.n_used},
        "aliased_diagonal": {
            "status": alias.status,
            "condition_number": alias.condition_number,
            "n_used": alias.n_used,
        },
    }
