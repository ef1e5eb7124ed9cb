"""Null calibration: detection thresholds from the diagnoser run on
simulated-on-simulated logs (a seeded Monte Carlo), not from chi-square
tables, stored with the false-alarm rate they give.

The committed calibrations (bench/gap/data/null_calibration.json, and
null_calibration_characterisation.json for logs that also fly the thruster
characterisation after docking) are made by the campaign of
bench/campaigns/gap/null_calibration.py:
    python -m bench.commands.null_calibration --runs 1000 --seed 1000 --workers 2
    python -m bench.commands.null_calibration --runs 1000 --seed 1001 --manoeuvres docking+characterisation

(each run a Dask task, kept in a results store as it finishes; add
``--scheduler tcp://HOST:PORT`` for a cluster, docs/CAMPAIGNS.md)

Each statistic gets the threshold that leaves FA_EACH of the null runs above
it (the empirical quantile, a little beyond the largest value when there are
few runs); the stored ``false_alarm_rate`` is the fraction of the null runs
that either statistic flags.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parent / "data" / "null_calibration.json"
DATA_BY_MANOEUVRES = {
    "docking": DATA,
    "docking+characterisation": DATA.with_name("null_calibration_characterisation.json"),
}
FA_EACH = 0.005


def load(path=DATA, manoeuvres: str | None = None) -> dict:
    """The null calibration at ``path``, or the committed one for logs that
    fly ``manoeuvres`` (bench/sim/plans.py MANOEUVRES)."""
    p = Path(DATA_BY_MANOEUVRES[manoeuvres] if manoeuvres is not None else path)
    if not p.exists():
        return {}
    return json.loads(p.read_text())


def quantile_threshold(values: np.ndarray, fa: float) -> float:
    """The threshold a null value exceeds with probability ``fa``: midway
    between the order statistics around the (1 - fa) quantile, or just beyond
    the largest value when there are too few values for that quantile."""
    v = np.sort(np.asarray(values, float))
    k = int(np.floor((1.0 - fa) * v.size))
    if k >= v.size - 1:  # too few runs for that quantile: just beyond the largest
        return float(v[-1] + 0.05 * (v[-1] - v[0] + 1e-9))
    return float(0.5 * (v[k] + v[k + 1]))
