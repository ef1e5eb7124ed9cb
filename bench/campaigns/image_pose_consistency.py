"""Per-frame consistency of the image poses along the docking scenario: the
docking runs flown on image poses (bench/sim/scenario_docking.py, pose_source
"images") give the true trajectory; the host's pattern is rendered from it
and each pose from the flight vision pipeline (bench/sim/image_pose.py) is
compared with the truth (docs/VISION.md, "Navigation on image poses")."""

from __future__ import annotations

import numpy as np

from bench.sim.image_pose import ImagePoseSensor
from bench.sim.sensors import NoiseProfile


def pose_nees_along_docking(
    seeds=(1000, 1003), render_seed: int = 7, renders: int = 3, range_bins_m=(0.0, 0.3, 0.4, 0.5, 0.6, 0.8)
) -> dict:
    """Per-frame consistency of the image poses on the docking scenario.

    Each seed's docking run (pose from images) gives the true trajectory; at
    every whole second the pattern is rendered ``renders`` times from the
    truth (its own random stream, ``render_seed``) and each pose is compared with
    the truth: NEES against the reported R (6 dof), whole and in blocks,
    and its mean per range bin (camera to pattern centre)."""
    from scipy.stats import chi2

    from bench.sim.scenario_docking import ScenarioConfig, run_docking
    from bench.so3 import boxminus

    sensor = ImagePoseSensor(NoiseProfile.paper(), np.random.default_rng(render_seed))
    nees, npos, natt, rng_m = [], [], [], []
    for seed in seeds:
        run = run_docking(seed, ScenarioConfig(pose_source="images"))
        t = np.asarray(run.t)
        for k in np.flatnonzero(np.abs(t - np.round(t)) < 1e-6):
            r, q = np.asarray(run.r_true[k]), np.asarray(run.q_true[k])
            for _ in range(renders):
                m = sensor.measure(float(t[k]), r, q)
                if m is None:
                    continue
                e = np.concatenate([m.r_hill_m - r, boxminus(m.q_hb, q)])
                nees.append(float(e @ np.linalg.solve(m.R, e)))
                npos.append(float(e[:3] @ np.linalg.solve(m.R[:3, :3], e[:3])))
                natt.append(float(e[3:] @ np.linalg.solve(m.R[3:, 3:], e[3:])))
                rng_m.append(float(sensor.last.range_m))
    nees, rng_m = np.array(nees), np.array(rng_m)
    bins = []
    for lo, hi in zip(range_bins_m[:-1], range_bins_m[1:]):
        sel = (rng_m >= lo) & (rng_m < hi)
        if sel.any():
            bins.append({"range_m": [lo, hi], "frames": int(sel.sum()), "nees_mean": float(nees[sel].mean())})
    k = len(nees)
    return {
        "seeds": list(seeds),
        "frames": k,
        "nees_mean": float(nees.mean()),
        "nees_mean_band95_independent": [float(chi2.ppf(0.025, 6 * k) / k), float(chi2.ppf(0.975, 6 * k) / k)],
        "nees_pos_mean": float(np.mean(npos)),
        "nees_att_mean": float(np.mean(natt)),
        "by_range": bins,
        "status_counts": sensor.status_counts,
    }


if __name__ == "__main__":
    # OPENBLAS_NUM_THREADS=1 python -m bench.campaigns.image_pose_consistency  (docs/VISION.md, "Navigation on image poses")
    import json

    print(json.dumps(pose_nees_along_docking()))
