"""The bundled reality run that `make run` diagnoses.

A 120 s docking log from the bench's truth plant with one physical effect
switched on. The log (bench/gap/data/reality_run.h5) holds only what a user's
log holds: no truth, no effect. The effect is sealed apart in
reality_run.key.json with its sha256; `proxops run` opens it only after the
diagnosis has printed its answers, to compare.

Regenerate both (seeded, so the files reproduce):
    python -m bench.gap.bundled
A longer log with the same effect (for timing the diagnosis of a 10-minute log):
    python -m bench.gap.bundled --duration 600 --log LOG600.h5 --key KEY600.json
"""

from __future__ import annotations

import argparse
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


def generate(log_path=LOG, key_path=KEY, duration_s: float = DURATION_S) -> dict:
    from bench.gap.validate import blind
    from bench.sim.flight_log import write_flight_log
    from bench.sim.reality import simulate_log_with_key

    log, key = simulate_log_with_key(SEED, EFFECTS, duration_s=duration_s, with_truth=False)
    write_flight_log(log_path, blind(log))
    cmd = "python -m bench.gap.bundled" + ("" if duration_s == DURATION_S else f" --duration {duration_s:g}")
    key = {**key, "command": cmd}
    Path(key_path).write_text(json.dumps(key, indent=1) + "\n")
    return key


def sealed_key(key_path=KEY) -> dict:
    return json.loads(Path(key_path).read_text())


def main(argv=None):
    ap = argparse.ArgumentParser(description="regenerate the bundled reality run")
    ap.add_argument("--log", default=str(LOG))
    ap.add_argument("--key", default=str(KEY))
    ap.add_argument("--duration", type=float, default=DURATION_S, help="simulated seconds (chained docking runs)")
    a = ap.parse_args(argv)
    if not a.duration > 0:
        raise SystemExit("--duration must be > 0")
    key = generate(a.log, a.key, a.duration)
    print(f"wrote {a.log} and {a.key} (sha256 {key['sha256'][:12]})")


if __name__ == "__main__":
    main()
