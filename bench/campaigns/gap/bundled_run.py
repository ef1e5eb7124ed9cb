"""The bundled reality run (bench/gap/bundled.py), made again: the seeded
docking log with its effect, stripped to what a user's log holds, and its
sealed key.

    python -m bench.campaigns.gap.bundled_run
A longer log with the same effect (for timing the diagnosis of a 10-minute log):
    python -m bench.campaigns.gap.bundled_run --duration 600 --log LOG600.h5 --key KEY600.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from bench.gap.bundled import DURATION_S, EFFECTS, KEY, LOG, SEED


def generate(log_path=LOG, key_path=KEY, duration_s: float = DURATION_S) -> dict:
    from bench.campaigns.gap.validate import blind
    from bench.sim.flight_log import write_flight_log
    from bench.sim.reality import simulate_log_with_key

    log, key = simulate_log_with_key(SEED, EFFECTS, duration_s=duration_s, with_truth=False)
    write_flight_log(log_path, blind(log))
    cmd = "python -m bench.campaigns.gap.bundled_run" + (
        "" if duration_s == DURATION_S else f" --duration {duration_s:g}"
    )
    key = {**key, "command": cmd}
    Path(key_path).write_text(json.dumps(key, indent=1) + "\n")
    return key


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
