"""The bundled reality run that `make run` diagnoses.

A 120 s docking log from the bench's truth plant with one physical effect
switched on. The log (bench/gap/data/reality_run.h5) holds only what a user's
log holds: no truth, no effect. The effect is sealed apart in
reality_run.key.json with its sha256; `proxops run` opens it only after the
diagnosis has printed its answers, to compare.

Both are made again (seeded, so the files reproduce) by
bench/campaigns/gap/bundled_run.py:
    python -m bench.campaigns.gap.bundled_run
"""

from __future__ import annotations

import json
from pathlib import Path

DATA = Path(__file__).resolve().parent / "data"
LOG = DATA / "reality_run.h5"
KEY = DATA / "reality_run.key.json"

SEED = 20261123
DURATION_S = 120.0
# Thruster 3 has lost 6 % of its thrust and thruster 6 4 %: a partly blocked
# nozzle, the commonest cold-gas fault.
EFFECTS = {"thrust_loss": [0.0, 0.0, 0.0, 0.06, 0.0, 0.0, 0.04, 0.0]}


def sealed_key(key_path=KEY) -> dict:
    return json.loads(Path(key_path).read_text())
