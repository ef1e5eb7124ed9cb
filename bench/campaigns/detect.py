"""The smallest magnitude of each physical effect that shows as a gap in
docking logs (docs/EFFECTS.md, "How min_detectable was measured"), measured
on the reality runs of bench/sim/reality.py: ``gap_statistics`` of chained
runs against a null of effect-free runs, and ``measure_min_detectable``
searching the size whose median gap score reaches the detection threshold:

    python -m bench.campaigns.detect --seeds 4 --json out.json
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from bench.sim.effects import EFFECTS
from bench.sim.reality import DT_S, simulate_runs
from bench.sim.scenario_docking import ScenarioConfig
from bench.sim.vehicle import Vehicle


def _rss(y: np.ndarray, x: np.ndarray) -> float:
    beta, *_ = np.linalg.lstsq(x, y, rcond=None)
    return float(np.sum((y - x @ beta) ** 2))


def gap_statistics(runs: list) -> dict:
    """Gap statistics of chained runs, each near 1 under the nominal model:
    nis:        mean NIS of the pose updates / 6;
    innov_bias: N |mean whitened innovation|^2 / 6 (a constant offset);
    accel:      mean |a_meas - F(valves)/m|^2 / (3 sigma_a^2): replay of the
                accelerometer against the nominal thrusters;
    accel_fit:  the part of that residual explained by a per-valve force
                error and a constant, chi-square / 27;
    gyro:       mean |d|^2 / (6 sigma_g^2), d = the change of the gyro
                sample minus the nominal rate change from the valve torques;
    gyro_fit:   the gyro samples minus the nominal rate history (valve
                torques integrated from an unknown initial rate per run):
                the part explained by per-valve torque errors (regressors:
                each valve's cumulative open time), chi-square / 24;
    nees:       (truth only) mean NEES / 9 of the estimate against the
                truth from the first pose update on.
    """
    v = Vehicle()
    f_tab, tau_tab = v.config_table()
    alpha_tab = tau_tab @ np.linalg.inv(v.inertia_kgm2).T
    valves_tab = np.array([[(k >> i) & 1 for i in range(8)] for k in range(256)], dtype=float)
    sc = ScenarioConfig()
    sa, sg = sc.profile.accel_sigma_mps2, sc.profile.gyro_sigma_rps
    nis, white, ea, xa, eg, xg, wg, nees = [], [], [], [], [], [], [], []
    for r in runs:
        t0 = r.summary.first_update_t_s
        if t0 is not None:
            nees.extend(r.nees[r.t >= t0 - 1e-9])
        u = r.updates
        ok = np.asarray(u.status) != "bad_input"
        nis.extend(np.asarray(u.nis)[ok])
        for nu, S in zip(np.asarray(u.innovation)[ok], np.asarray(u.S)[ok]):
            white.append(np.linalg.solve(np.linalg.cholesky(S), nu))
        cfgs = r.config
        n = min(cfgs.size, len(r.imu_accel))
        ea.append(r.imu_accel[:n] - f_tab[cfgs[:n]] / v.mass_kg)
        xa.append(np.column_stack([valves_tab[cfgs[:n]], np.ones(n)]))
        al = alpha_tab[cfgs[:n]]
        eg.append(np.diff(r.imu_gyro[:n], axis=0) - 0.5 * (al[:-1] + al[1:]) * DT_S)
        vv = valves_tab[cfgs[:n]]
        # Mean rate over interval k: w0 + sum_{j<k} alpha_j dt + alpha_k dt / 2.
        cum_v = (np.cumsum(vv, axis=0) - 0.5 * vv) * DT_S
        cum_a = (np.cumsum(al, axis=0) - 0.5 * al) * DT_S
        wg.append(r.imu_gyro[:n] - cum_a)
        xg.append(cum_v)
    white = np.array(white).reshape(-1, 6)
    # One unknown initial rate per run: an intercept column per run.
    blocks = [np.zeros((len(w), len(wg))) for w in wg]
    for i, b in enumerate(blocks):
        b[:, i] = 1.0
    x0 = np.concatenate(blocks)
    ea, xa, eg, xg, wg = (np.concatenate(z) for z in (ea, xa, eg, xg, wg))
    return {
        "nis": float(np.mean(nis) / 6.0) if nis else float("nan"),
        "innov_bias": float(len(white) * np.sum(np.mean(white, axis=0) ** 2) / 6.0) if len(white) else float("nan"),
        "accel": float(np.mean(np.sum(ea**2, axis=1)) / (3 * sa * sa)),
        "accel_fit": (float(np.sum(ea**2)) - _rss(ea, xa)) / (sa * sa * 27),
        "gyro": float(np.mean(np.sum(eg**2, axis=1)) / (6 * sg * sg)),
        "gyro_fit": (_rss(wg, x0) - _rss(wg, np.column_stack([x0, xg]))) / (sg * sg * 24),
        "nees": float(np.mean(nees) / 9.0) if nees else float("nan"),
    }


STAT_NAMES = ("nis", "innov_bias", "accel", "accel_fit", "gyro", "gyro_fit")  # from the sensors alone
TRUTH_STAT_NAMES = STAT_NAMES + ("nees",)


def scenario_for(name: str) -> ScenarioConfig | None:
    """The docking scenario an effect is measured in: pose from rendered
    images for an effect of the camera (EffectSpec.needs_images)."""
    return ScenarioConfig(pose_source="images") if EFFECTS[name].needs_images else None


def null_statistics(seeds, duration_s: float = 120.0, scenario: ScenarioConfig | None = None) -> dict:
    vals = {k: [] for k in TRUTH_STAT_NAMES}
    for s in seeds:
        st = gap_statistics(simulate_runs(int(s), None, duration_s, scenario))
        for k in TRUTH_STAT_NAMES:
            vals[k].append(st[k])
    return {k: {"mean": float(np.mean(x)), "std": float(np.std(x, ddof=1)), "values": x} for k, x in vals.items()}


def gap_score(stats: dict, null: dict, names=STAT_NAMES) -> tuple[float, str]:
    """Largest deviation above the null mean in null standard deviations, and its statistic."""
    z = {k: (stats[k] - null[k]["mean"]) / null[k]["std"] for k in names}
    k = max(z, key=z.get)
    return float(z[k]), k


def score_at(name: str, size: float, seeds, null: dict, duration_s: float = 120.0, rng_seed: int = 0, names=STAT_NAMES):
    """Median gap score over ``seeds`` for effect ``name`` drawn at ``size``
    (a new random direction per seed)."""
    spec = EFFECTS[name]
    rng = np.random.default_rng(rng_seed)
    scores, which = [], []
    for s in seeds:
        p = spec.draw_fn(rng, size)
        sc, k = gap_score(gap_statistics(simulate_runs(int(s), {name: p}, duration_s, scenario_for(name))), null, names)
        scores.append(sc)
        which.append(k)
    return float(np.median(scores)), scores, which


def measure_min_detectable(
    name: str,
    seeds,
    null: dict,
    z_detect: float = 4.0,
    duration_s: float = 120.0,
    start: float | None = None,
    max_evals: int = 7,
    log=print,
    names=STAT_NAMES,
) -> dict:
    """Smallest size whose median gap score reaches z_detect. The score of a
    chi-square-like statistic grows about as size^2, so each next size is
    size * sqrt(z_detect / score) (a step of at most x10, x10 up when the score
    is not above zero, never past the effect's max_size); once two sizes
    bracket z_detect the answer is the linear interpolation of the score in
    log(size) between the closest two; NaN if max_size does not reach it."""
    spec = EFFECTS[name]
    size = float(start if start is not None else spec.typical)
    tried = {}
    for _ in range(max_evals):
        med, sc, wh = score_at(name, size, seeds, null, duration_s, names=names)
        tried[size] = {"median": med, "scores": sc, "stat": wh}
        log(f"  {name} size {size:.4g} {spec.unit}: median score {med:.2f} ({', '.join(wh)})")
        below = [x for x in tried if tried[x]["median"] < z_detect]
        above = [x for x in tried if tried[x]["median"] >= z_detect]
        if below and above:
            lo, hi = max(below), min(above)
            if lo < hi and hi / lo <= 2.5:
                break
        step = 10.0 if med <= 0.0 else float(np.clip(np.sqrt(z_detect / med), 0.1, 10.0))
        nxt = size * step
        if below and above and lo < hi:
            nxt = float(np.sqrt(lo * hi))  # bisect in log(size) until the bracket is narrow
        nxt = min(nxt, spec.max_size)
        if nxt in tried:
            break
        size = nxt
    below = [x for x in tried if tried[x]["median"] < z_detect]
    above = [x for x in tried if tried[x]["median"] >= z_detect]
    if not (below and above) or max(below) > min(above):
        return {"effect": name, "min_detectable": float("nan"), "tried": tried}
    lo, hi = max(below), min(above)
    zl, zh = tried[lo]["median"], tried[hi]["median"]
    frac = (z_detect - zl) / (zh - zl) if zh != zl else 0.5
    md = float(np.exp(np.log(lo) + frac * (np.log(hi) - np.log(lo))))
    return {"effect": name, "min_detectable": md, "bracket": [lo, hi], "tried": tried}


def main(argv=None):
    ap = argparse.ArgumentParser(
        prog="python -m bench.campaigns.detect", description="measure min_detectable of effects"
    )
    ap.add_argument("--effects", nargs="*", default=list(EFFECTS))
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--null-seeds", type=int, default=12)
    ap.add_argument("--duration", type=float, default=120.0)
    ap.add_argument("--z", type=float, default=4.0)
    ap.add_argument("--json", required=True)
    ap.add_argument("--null-from", help="reuse the null statistics of an earlier --json output")
    a = ap.parse_args(argv)
    t0 = time.time()
    if a.null_from:
        with open(a.null_from) as f:
            null = json.load(f)["null"]
    else:
        null = null_statistics(range(900, 900 + a.null_seeds), a.duration)
    print("null:", {k: (round(v["mean"], 3), round(v["std"], 3)) for k, v in null.items()}, flush=True)
    out = {"null": null, "z_detect": a.z, "seeds": list(range(100, 100 + a.seeds)), "effects": {}}
    with open(a.json, "w") as f:
        json.dump(out, f, indent=1, default=float)
    null_synthetic = null
    for name in a.effects:
        spec = EFFECTS[name]
        null = null_synthetic
        if spec.needs_images:  # measured against a null of image-pose runs
            if "null_images" not in out:
                out["null_images"] = null_statistics(range(900, 900 + a.null_seeds), a.duration, scenario_for(name))
                print(
                    "null (pose from images):",
                    {k: (round(v["mean"], 3), round(v["std"], 3)) for k, v in out["null_images"].items()},
                    flush=True,
                )
            null = out["null_images"]
        res = {"effect": name, "min_detectable": float("nan"), "needs_truth": False, "detectable": True}
        for names, truth in ((STAT_NAMES, False), (TRUTH_STAT_NAMES, True)):
            # First the largest sensible size: if even that does not show, skip the search.
            at_max = (
                score_at(name, spec.max_size, out["seeds"], null, a.duration, names=names)
                if np.isfinite(spec.max_size)
                else (np.inf, [], [])
            )
            print(
                f"  {name} at max_size {spec.max_size:g}: median score {at_max[0]:.2f}"
                f"{' (with truth)' if truth else ''}",
                flush=True,
            )
            if at_max[0] < a.z:
                continue
            res = measure_min_detectable(
                name,
                out["seeds"],
                null,
                a.z,
                a.duration,
                start=spec.min_detectable,
                log=lambda m: print(m, flush=True),
                names=names,
            )
            res["needs_truth"], res["detectable"] = truth, True
            break
        else:
            res["detectable"] = False  # not even the truth shows it up to max_size
        out["effects"][name] = res
        print(
            f"{name}: min_detectable {res['min_detectable']:.4g} {EFFECTS[name].unit} ({time.time() - t0:.0f} s)",
            flush=True,
        )
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1, default=float)


if __name__ == "__main__":
    main()
