#!/usr/bin/env python3
"""Line and branch coverage of fsw/ from a build with gcov counters
(CMakePresets.json "coverage"; docs/ASSURANCE.md), read with gcovr once and
reported for the flight core, vision and the platform apart. Fails (exit 1)
when the core is under its floors; prints the core's uncovered lines, file
by file, for the review that lists each with its reason.

    coverage.py --build build/cov [--gcovr PATH] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# The parts and their filters (paths relative to the repository); the floors
# apply to the core.
PARTS = {
    "core": r"fsw/(include|src)/",
    "vision": r"fsw/vision/",
    "platform": r"fsw/platform/",
}
FLOORS = {"core": {"line": 95.0, "branch": 85.0}}


def _ranges(nums: list[int]) -> str:
    out, start, prev = [], None, None
    for n in sorted(nums):
        if start is None:
            start = prev = n
        elif n == prev + 1:
            prev = n
        else:
            out.append(f"{start}-{prev}" if prev != start else f"{start}")
            start = prev = n
    if start is not None:
        out.append(f"{start}-{prev}" if prev != start else f"{start}")
    return ", ".join(out)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build", type=Path, required=True)
    ap.add_argument("--gcovr", default="gcovr")
    ap.add_argument("--json", type=Path, help="write the figures here")
    args = ap.parse_args()
    build = args.build.resolve()
    full = build / "coverage-full.json"
    # One pass of gcov over every counter file; throw branches (exception
    # paths of the test harness's standard library calls) and branches the
    # compiler marks unreachable are not the flight code's.
    common = ["--exclude-throw-branches", "--exclude-unreachable-branches", "--gcov-ignore-parse-errors=all"]
    subprocess.run(
        [
            args.gcovr,
            "-r",
            str(ROOT),
            "--object-directory",
            str(build),
            "--filter",
            "fsw/",
            *common,
            "--json",
            str(full),
            "-j",
            "2",
        ],
        check=True,
        cwd=ROOT,
    )
    figures: dict = {}
    failed = []
    for part, filt in PARTS.items():
        summary = build / f"coverage-{part}.json"
        subprocess.run(
            [args.gcovr, "-r", str(ROOT), "-a", str(full), "--filter", filt, "--json-summary", str(summary)],
            check=True,
            cwd=ROOT,
            stdout=subprocess.DEVNULL,
        )
        s = json.loads(summary.read_text())
        fig = {
            "lines": [s["line_covered"], s["line_total"], s["line_percent"]],
            "branches": [s["branch_covered"], s["branch_total"], s["branch_percent"]],
        }
        figures[part] = fig
        print(
            f"{part:9s} lines {s['line_covered']:6d} / {s['line_total']:6d} = {s['line_percent']:5.1f} %   "
            f"branches {s['branch_covered']:6d} / {s['branch_total']:6d} = {s['branch_percent']:5.1f} %"
        )
        floor = FLOORS.get(part)
        if floor:
            if s["line_percent"] < floor["line"]:
                failed.append(f"{part}: lines {s['line_percent']} % < {floor['line']} %")
            if s["branch_percent"] < floor["branch"]:
                failed.append(f"{part}: branches {s['branch_percent']} % < {floor['branch']} %")
    data = json.loads(full.read_text())
    print("uncovered lines of the core:")
    for f in sorted(data["files"], key=lambda f: f["file"]):
        if not f["file"].startswith(("fsw/include/", "fsw/src/")):
            continue
        missed = sorted({ln["line_number"] for ln in f["lines"] if ln["count"] == 0 and not ln.get("gcovr/noncode")})
        if missed:
            print(f"  {f['file']}: {_ranges(missed)}")
    if args.json:
        args.json.write_text(json.dumps(figures, indent=1) + "\n")
    for msg in failed:
        print(f"coverage under its floor: {msg}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
