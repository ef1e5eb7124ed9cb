"""Timing of the modal frequency acquisition's search: the flight C++
(ModalAcquisition through the bindings) beside the numpy RELAX it is checked
against (bench/campaigns/modal_batch_ml.py: grid_start, relax_start with the joint
amplitude re-solve), on the same simulated plate histories, in one run; and
the flight replay of the joint filter over that history. Also says whether
the two searches picked the same grid frequencies.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python -m bench.perf.perf_modal_acquisition [--repeats N] [--json OUT]
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import time

import numpy as np

from bench.campaigns import modal_batch_ml
from bench.campaigns import modal_campaign as mc
from bench.report import write_json
from bench.sim import structure as st

# (modes, images, image interval [s]): two lowest-mode periods of the bench's runs
CASES = ((10, 80, 60.0), (50, 241, 20.0))


def plate_history(n_modes, n_images, dt_s, seed=0):
    """Decomposition records of one simulated plate run, their times and the
    a priori frequencies (10 % error), as the campaign makes them."""
    import fsw_bindings as fb

    rng = np.random.default_rng(seed)
    plate = st.Plate(n_modes=n_modes)
    sensor = st.plate_sensor(plate)
    amp, phase = st.plate_truth(plate, rng)
    w_prior = plate.omega_radps * (1 + rng.uniform(-0.1, 0.1, n_modes))
    dec = getattr(fb, f"ModalDecomposition{n_modes}")()
    recs, t = [], []
    for k in range(n_images):
        a = st.plate_coeffs(plate, amp, phase, k * dt_s)
        r_meas, d = st.plate_range_image(plate, sensor, a, rng, noise_frac=0.03)
        rec = dec.decompose(*st.plate_points(plate, sensor, r_meas, d, noise_frac=0.03))
        if rec.ok:
            recs.append(rec)
            t.append(k * dt_s)
    return recs, np.array(t), w_prior


def numpy_relax(coarse, cov, t, w_prior, sigma_w, n_grid=201):
    """The numpy reference: per-mode grid start, then RELAX with the coupled
    weights and the joint amplitude re-solve after every mode."""
    m = coarse.shape[1]
    wh = modal_batch_ml.whiteners(cov)

    def amplitudes(w):
        basis = np.concatenate(
            [
                np.cos(np.outer(t, w))[:, None, :] * np.eye(m)[None],
                np.sin(np.outer(t, w))[:, None, :] * np.eye(m)[None],
            ],
            axis=2,
        )
        a = np.einsum("kij,kjl->kil", wh, basis).reshape(-1, 2 * m)
        y = np.einsum("kij,kj->ki", wh, coarse).ravel()
        return np.linalg.lstsq(a, y, rcond=None)[0]

    var = np.diagonal(cov, axis1=1, axis2=2)
    w0 = modal_batch_ml.grid_start(coarse, var, t, w_prior, sigma_w, n_grid)
    return modal_batch_ml.relax_start(
        coarse, np.linalg.inv(cov), t, w_prior, sigma_w, w0, n_grid, amplitudes=amplitudes
    )


def _median_s(fn, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), out


def time_case(n_modes, n_images, dt_s, repeats, numpy_repeats):
    import fsw_bindings as fb

    recs, t, w_prior = plate_history(n_modes, n_images, dt_s)
    sigma_w = 0.1 * w_prior
    acq = getattr(fb, f"ModalAcquisition{n_modes}")(w_prior, sigma_w)
    for tk, r in zip(t, recs):
        acq.add(float(tk), r)

    def flight():
        if acq.search() != "ok":
            raise RuntimeError("flight search failed")
        return acq.omega

    s_flight, w_flight = _median_s(flight, repeats)
    coarse = np.array([r.a_coarse for r in recs])
    cov = np.array([r.cov_a for r in recs])
    s_numpy, w_numpy = _median_s(lambda: numpy_relax(coarse, cov, t, w_prior, sigma_w), numpy_repeats)
    filt = mc.make_filter(
        "joint",
        n_modes,
        w_flight,
        np.zeros(n_modes),
        sigma_v0=w_flight,
        sigma_w0=0.01 * w_flight,
        sigma_a0=1e-6,
        q_a=0.0,
        q_v=0.0,
    )
    s_replay, fused = _median_s(lambda: acq.replay_into(filt), repeats)
    return {
        "modes": n_modes,
        "images": len(recs),
        "flight_search_s": s_flight,
        "numpy_search_s": s_numpy,
        "speedup": s_numpy / s_flight,
        "same_grid_frequencies": bool(np.allclose(w_flight, w_numpy, rtol=1e-12)),
        "flight_replay_s": s_replay,
        "replay_fused": int(fused),
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=9, help="flight repeats (median)")
    ap.add_argument("--numpy-repeats", type=int, default=3, help="numpy repeats (median; ~9 s each at 50 modes)")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    if args.repeats < 1 or args.numpy_repeats < 1:
        ap.error("--repeats and --numpy-repeats must be at least 1")
    cpu = subprocess.run("lscpu | grep 'Model name'", shell=True, capture_output=True, text=True).stdout.strip()
    out = {
        "cpu": cpu,
        "nproc": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "openblas_threads": os.environ.get("OPENBLAS_NUM_THREADS"),
        "loadavg_1min": os.getloadavg()[0],
        "cases": [],
    }
    print(f"{cpu}; nproc {out['nproc']}; 1-min load average {out['loadavg_1min']:.1f}")
    for m, n, dt in CASES:
        r = time_case(m, n, dt, args.repeats, args.numpy_repeats)
        out["cases"].append(r)
        print(
            f"{m} modes, {r['images']} images: search flight {1e3 * r['flight_search_s']:.1f} ms, numpy "
            f"{1e3 * r['numpy_search_s']:.0f} ms ({r['speedup']:.0f}x), same grid frequencies "
            f"{r['same_grid_frequencies']}; flight replay of the joint filter {1e3 * r['flight_replay_s']:.1f} ms"
        )
    if args.json:
        write_json(args.json, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
