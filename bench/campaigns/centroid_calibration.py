"""Calibration of the LED centroid error model against rendered spots
(docs/VISION.md, "Centroid error model").

Single LED spots are rendered exactly as bench/sim/camera.py renders the pattern
(pixel-integrated Gaussian, background, optional Gaussian blur, read and shot
noise, saturation at 255, 8-bit rounding), on a grid so that one image holds
many spots, and passed through the flight detector
(``fsw_bindings.LedPoseEstimator.detect``). Each detected centroid is compared
with the spot's true position:

    error e = centroid - truth (u and v pooled), and z = e / sigma_model

per spot, with sigma_model the sigma the detector reports. Per bin of peak
level (faint, bright, saturated), spot width and blur: detection rate, bias
(mean e), rms error against rms model sigma, and mean z^2 (1 when the model is
honest).

Model (``fsw_vision`` detector, refined centroid): per spot

    sigma^2 = centroid_noise_scale^2 sigma_noise^2
              + (sat_sigma_px n_sat / max(width / 1 px, 1)^4)^2
              + centroid_floor_px^2

with sigma_noise the pixel noise propagated through the Gaussian-weighted
centroid (ring background variance plus shot noise, and the background
plane's error), n_sat the saturated pixels in the window and width the
spot's width from its moments (the saturation term's form was chosen by
likelihood over the same spots among n_sat^a / width^b, a in 0 to 3, b in
2 to 12). ``fit`` chooses
the three constants by non-negative least squares on the per-spot squared
errors, reweighted by the model variance's inverse square (the Gaussian
likelihood's weights for a variance); the check re-renders with the next
seed through the flight defaults. ``--legacy`` also measures the first
estimate alone (component box + 2 px, weights clipped at zero, plain
pixel-noise sigma), the detector before the refinement. Command:

    OPENBLAS_NUM_THREADS=1 python -m bench.campaigns.centroid_calibration --seed 1 --images 60 --legacy

It prints the table and the fitted constants; ``--json`` writes them.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from scipy.ndimage import gaussian_filter

from bench.sim import camera as cm

SPACING_PX = 48
MARGIN_PX = 24


def spot_grid(width: int = cm.WIDTH, height: int = cm.HEIGHT) -> np.ndarray:
    """(N, 2) nominal spot centres [u, v]: a grid SPACING_PX apart, MARGIN_PX inside the image."""
    us = np.arange(MARGIN_PX, width - MARGIN_PX + 1, SPACING_PX)
    vs = np.arange(MARGIN_PX, height - MARGIN_PX + 1, SPACING_PX)
    uu, vv = np.meshgrid(us, vs)
    return np.column_stack([uu.ravel(), vv.ravel()]).astype(float)


def draw_spots(
    rng: np.random.Generator,
    flux_range=(60.0, 150000.0),
    led_sigma_range=(0.05, 4.0),
    psf_sigma_px: float = 0.8,
    blur_sigma_px: float = 0.0,
    scene: cm.Scene | None = None,
):
    """One image of spots at random sub-pixel positions on the grid.

    Flux log-uniform in flux_range [counts]; the LED's own angular size
    (sigma) log-uniform in led_sigma_range [px], combined with the PSF as
    the renderer does. Returns (image uint8, truth (N, 2), flux (N,),
    sigma_px (N,): spot width before the blur)."""
    scene = cm.Scene() if scene is None else scene
    grid = spot_grid()
    n = len(grid)
    truth = grid + rng.uniform(-0.5, 0.5, size=(n, 2))
    flux = np.exp(rng.uniform(*np.log(flux_range), size=n))
    sig = np.hypot(psf_sigma_px, np.exp(rng.uniform(*np.log(led_sigma_range), size=n)))
    img = np.full((cm.HEIGHT, cm.WIDTH), scene.background_counts, float)
    for (u, v), f, s in zip(truth, flux, sig):
        cm.gauss_patch(img, u, v, s, f)
    if blur_sigma_px > 0:
        img = gaussian_filter(img, blur_sigma_px, mode="nearest")
    var = scene.read_noise_counts**2 + scene.shot_gain * np.maximum(img - scene.background_counts, 0.0)
    img = img + np.sqrt(var) * rng.standard_normal(img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8), truth, flux, sig


def measure(est, seed: int, images: int, blur_values=(0.0, 2.0), match_px: float = 2.0) -> dict:
    """Renders ``images`` images per blur value and matches the detector's blobs to the truth.

    Returns arrays per spot: blur, flux, sigma (before blur), peak (the
    brightest pixel's noise-free value before clipping), detected, err_u,
    err_v, sigma_model, area."""
    rng = np.random.default_rng(seed)
    cols = {
        k: []
        for k in (
            "blur",
            "flux",
            "sigma",
            "peak",
            "detected",
            "err_u",
            "err_v",
            "sigma_model",
            "area",
            "n_sat",
            "sigma_noise",
            "width",
            "phase_u",
            "phase_v",
        )
    }
    max_blobs = est.config.max_blobs
    for blur in blur_values:
        for _ in range(images):
            img, truth, flux, sig = draw_spots(rng, blur_sigma_px=blur)
            blobs = _detect_all(est, img, max_blobs)
            s_eff = np.hypot(sig, blur)
            peak = flux * (_erf_pixel(s_eff) ** 2)
            for _i, (t, f, s, p) in enumerate(zip(truth, flux, sig, peak)):
                cols["blur"].append(blur)
                cols["flux"].append(f)
                cols["sigma"].append(s)
                cols["peak"].append(p)
                if len(blobs):
                    d = np.hypot(blobs[:, 0] - t[0], blobs[:, 1] - t[1])
                    j = int(np.argmin(d))
                    hit = d[j] < match_px
                else:
                    hit = False
                cols["detected"].append(hit)
                cols["err_u"].append(blobs[j, 0] - t[0] if hit else np.nan)
                cols["err_v"].append(blobs[j, 1] - t[1] if hit else np.nan)
                cols["sigma_model"].append(blobs[j, 4] if hit else np.nan)
                cols["area"].append(blobs[j, 3] if hit else np.nan)
                cols["n_sat"].append(blobs[j, 5] if hit else np.nan)
                cols["sigma_noise"].append(blobs[j, 6] if hit else np.nan)
                cols["width"].append(blobs[j, 7] if hit else np.nan)
                cols["phase_u"].append(t[0] - np.rint(t[0]))
                cols["phase_v"].append(t[1] - np.rint(t[1]))
    return {k: np.asarray(v, float) for k, v in cols.items()}


def _erf_pixel(s):
    """Fraction of a centred Gaussian spot of width s [px] in its central pixel (1-D)."""
    from scipy.special import erf

    return erf(0.5 / (np.sqrt(2.0) * np.asarray(s, float)))


def _detect_all(est, img, max_blobs):
    # The detector keeps the max_blobs brightest: it must keep every grid spot.
    if max_blobs < len(spot_grid()):
        raise ValueError("max_blobs must be at least the number of grid spots (use estimator())")
    return est.detect(img)


def estimator(**overrides):
    """The flight pipeline's estimator with the bench camera, max_blobs raised for the spot grid."""
    import fsw_bindings as fb

    base = cm.make_estimator(cm.Camera())
    cfg = base.config
    cfg.max_blobs = len(spot_grid()) + 20
    for k, v in overrides.items():
        setattr(cfg, k, v)
    return fb.LedPoseEstimator(cfg)


# The detector before the refinement: first estimate and its pixel-noise sigma with the 0.008 px floor,
# plain threshold only (no faint-spot pass).
LEGACY = {"refine_centroid": False, "centroid_floor_px": 0.008, "faint_sigma_px": 0.0}

PEAK_CLASSES = (("faint", 0.0, 60.0), ("bright", 60.0, 249.0), ("saturated", 249.0, np.inf))
SIGMA_CLASSES = (("undersampled", 0.0, 1.0), ("1-1.6 px", 1.0, 1.6), ("1.6-2.5 px", 1.6, 2.5), ("wide", 2.5, np.inf))


def table(d: dict) -> list[dict]:
    """Per (blur, peak class, width class): detection, bias, rms error, rms model sigma, mean z^2."""
    rows = []
    for blur in np.unique(d["blur"]):
        for pname, plo, phi in PEAK_CLASSES:
            for sname, slo, shi in SIGMA_CLASSES:
                sel = (
                    (d["blur"] == blur)
                    & (d["peak"] >= plo)
                    & (d["peak"] < phi)
                    & (d["sigma"] >= slo)
                    & (d["sigma"] < shi)
                )
                n = int(sel.sum())
                if n < 20:
                    continue
                det = sel & (d["detected"] > 0)
                k = int(det.sum())
                row = {"blur_px": float(blur), "peak": pname, "width": sname, "spots": n, "detected": k}
                if k >= 10:
                    e = np.concatenate([d["err_u"][det], d["err_v"][det]])
                    s = np.concatenate([d["sigma_model"][det], d["sigma_model"][det]])
                    ph = np.concatenate([d["phase_u"][det], d["phase_v"][det]])
                    row.update(
                        bias_px=float(np.mean(e)),
                        rms_err_px=float(np.sqrt(np.mean(e**2))),
                        rms_sigma_px=float(np.sqrt(np.mean(s**2))),
                        mean_z2=float(np.mean((e / s) ** 2)),
                        phase_bias_px=phase_bias(e, ph),
                    )
                rows.append(row)
    return rows


def phase_bias(e, phase) -> float:
    """Amplitude [px] of the error's dependence on the sub-pixel phase: least-squares fit of
    e = a sin(2 pi phase) + b sin(4 pi phase) (the pull towards, or away from, pixel centres);
    returns sqrt(a^2 + b^2)."""
    A = np.column_stack([np.sin(2 * np.pi * phase), np.sin(4 * np.pi * phase)])
    c = np.linalg.lstsq(A, e, rcond=None)[0]
    return float(np.hypot(*c))


def overall(d: dict) -> dict:
    det = d["detected"] > 0
    out = {}
    for blur in np.unique(d["blur"]):
        sel = det & (d["blur"] == blur)
        e = np.concatenate([d["err_u"][sel], d["err_v"][sel]])
        s = np.concatenate([d["sigma_model"][sel], d["sigma_model"][sel]])
        z2 = (e / s) ** 2
        out[f"blur_{blur:g}"] = {
            "detected": int(sel.sum()),
            "mean_z2": float(np.mean(z2)),
            "frac_abs_z_below_2": float(np.mean(np.abs(e / s) < 2.0)),
            "max_abs_z": float(np.max(np.abs(e / s))),
        }
    return out


def fit(d: dict, iterations: int = 5) -> dict:
    """Constants of sigma^2 = noise_scale^2 sigma_noise^2 + (sat_sigma_px n_sat / max(width, 1)^4)^2
    + floor^2 from the
    per-spot squared errors (u and v pooled): non-negative least squares on e^2, reweighted by the
    model variance's inverse square (the Gaussian likelihood's weights for a variance)."""
    from scipy.optimize import nnls

    det = (d["detected"] > 0) & np.isfinite(d["sigma_noise"])
    e2 = np.concatenate([d["err_u"][det] ** 2, d["err_v"][det] ** 2])
    vn = np.tile(d["sigma_noise"][det] ** 2, 2)
    ns = np.tile(d["n_sat"][det] ** 2 / np.maximum(d["width"][det], 1.0) ** 8, 2)
    A = np.column_stack([vn, ns, np.ones_like(vn)])
    w = 1.0 / np.maximum(vn, 1e-8)
    for _ in range(iterations):
        c, _ = nnls(A * w[:, None], e2 * w)
        pred = A @ c
        w = 1.0 / np.maximum(pred, 1e-8)
    return {
        "centroid_noise_scale": float(np.sqrt(c[0])),
        "sat_sigma_px": float(np.sqrt(c[1])),
        "centroid_floor_px": float(np.sqrt(c[2])),
        "spots": int(det.sum()),
    }


def print_table(rows: list[dict]) -> None:
    print(
        f"{'blur':>4} {'peak':<9} {'width':<13} {'spots':>5} {'det':>5} {'bias':>8} {'phase':>7} {'rms err':>8} "
        f"{'rms sig':>8} {'mean z2':>8}"
    )
    for r in rows:
        if "mean_z2" in r:
            print(
                f"{r['blur_px']:>4.1f} {r['peak']:<9} {r['width']:<13} {r['spots']:>5} {r['detected']:>5} "
                f"{r['bias_px']:>8.4f} {r['phase_bias_px']:>7.4f} {r['rms_err_px']:>8.4f} {r['rms_sigma_px']:>8.4f} {r['mean_z2']:>8.2f}"
            )
        else:
            print(f"{r['blur_px']:>4.1f} {r['peak']:<9} {r['width']:<13} {r['spots']:>5} {r['detected']:>5}")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m bench.campaigns.centroid_calibration", description=__doc__.split("\n")[0]
    )
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--images", type=int, default=60, help="images per blur value (130 spots each)")
    p.add_argument("--json", default=None)
    p.add_argument("--legacy", action="store_true", help="also measure the component-box centroid (before)")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    res = {"seed": args.seed, "images": args.images}
    if args.legacy:
        d = measure(estimator(**LEGACY), args.seed, args.images)
        res["legacy"] = {"rows": table(d), "overall": overall(d)}
        print("component-box centroid, pixel-noise sigma (before):")
        print_table(res["legacy"]["rows"])
        print(json.dumps(res["legacy"]["overall"], indent=1))
    # Fit on seed, check on seed + 1 with the flight defaults and with the fitted constants.
    d = measure(estimator(), args.seed, args.images)
    res["fit"] = fit(d)
    print("fitted:", json.dumps(res["fit"]))
    flight = estimator()
    cfg = flight.config
    res["flight_defaults"] = {k: getattr(cfg, k) for k in ("centroid_noise_scale", "sat_sigma_px", "centroid_floor_px")}
    d = measure(flight, args.seed + 1, args.images)
    res["check"] = {"seed": args.seed + 1, "rows": table(d), "overall": overall(d)}
    print(f"refined centroid with the flight defaults {res['flight_defaults']}, seed {args.seed + 1}:")
    print_table(res["check"]["rows"])
    print(json.dumps(res["check"]["overall"], indent=1))
    res["wall_s"] = time.perf_counter() - t0
    if args.json:
        from bench.report import write_json

        write_json(args.json, res)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
