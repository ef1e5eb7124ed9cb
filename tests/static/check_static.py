#!/usr/bin/env python3
"""Static analysis of the flight code (docs/ASSURANCE.md): clang-tidy with
the checks of fsw/.clang-tidy on every translation unit under fsw/ (and the
fsw headers they include), and cppcheck with the options below. Prints each
finding as path:line: tool: message [check] and exits 1 when there is any;
a finding accepted on purpose is suppressed in place, with its reason, by
a NOLINT comment (clang-tidy) or a cppcheck-suppress comment (cppcheck).

    check_static.py --build BUILD_DIR [--jobs N] [--tool clang-tidy|cppcheck|all]

BUILD_DIR holds compile_commands.json (a configure with
CMAKE_EXPORT_COMPILE_COMMANDS=ON; nothing needs to be built).
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FSW = ROOT / "fsw"

# cppcheck: the checks that find defects (warning), and the performance,
# portability and style checks; the include paths of the flight code but
# not Eigen's or OpenCV's (their code is not ours to analyse).
CPPCHECK_ARGS = [
    "--std=c++17",
    "--language=c++",
    "--enable=warning,style,performance,portability",
    "--inline-suppr",
    "--error-exitcode=0",
    "-q",
    "--suppress=missingIncludeSystem",
    # A raw loop in place of <numeric> or <algorithm> is this code's style:
    # fixed-size loops read alike in the flight and the firmware builds.
    "--suppress=useStlAlgorithm",
    # A local named like a member function (the filter equations' P,
    # config_ok) cannot be called by mistake: the call does not compile.
    # Shadowed variables (shadowVariable, shadowArgument) stay reported.
    "--suppress=shadowFunction",
    "-I",
    "fsw/include",
    "-I",
    "fsw/vision/include",
    "-I",
    "fsw/platform",
    "--template={file}:{line}: cppcheck: {message} [{id}]",
]
CPPCHECK_PATHS = ["fsw/src", "fsw/vision/src", "fsw/platform"]

FINDING = re.compile(r"^(?P<path>/[^:]+):(?P<line>\d+):\d+: (?P<kind>warning|error): (?P<msg>.*)$")


def _rel(path: str) -> str:
    p = Path(path).resolve()
    try:
        return str(p.relative_to(ROOT))
    except ValueError:
        return str(p)


def run_clang_tidy(build: Path, jobs: int, only: str = "") -> list[str]:
    exe = shutil.which("clang-tidy-14") or shutil.which("clang-tidy")
    if exe is None:
        sys.exit("check_static: clang-tidy not found (Debian package clang-tidy)")
    db = json.loads((build / "compile_commands.json").read_text())
    units = sorted({e["file"] for e in db if Path(e["file"]).resolve().is_relative_to(FSW)})
    units = [u for u in units if re.search(only, _rel(u))]
    if not units:
        sys.exit(f"check_static: no translation unit under fsw/ in {build}/compile_commands.json")

    def one(unit: str) -> tuple[str, str, float]:
        t0 = time.monotonic()
        r = subprocess.run([exe, "-p", str(build), "--quiet", unit], capture_output=True, text=True, cwd=ROOT)
        return unit, r.stdout + r.stderr, time.monotonic() - t0

    found: set[str] = set()
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        for unit, out, dt in pool.map(one, units):
            new = set()
            for line in out.splitlines():
                m = FINDING.match(line)
                if m and Path(m["path"]).resolve().is_relative_to(FSW):
                    new.add(f"{_rel(m['path'])}:{m['line']}: clang-tidy: {m['msg']}")
            print(f"  clang-tidy {_rel(unit)}: {dt:.0f} s, {len(new - found)} new finding(s)", flush=True)
            for f in sorted(new - found):
                print(f"    {f}", flush=True)
            found |= new
    return sorted(found)


def run_cppcheck(build: Path) -> list[str]:
    exe = shutil.which("cppcheck")
    if exe is None:
        sys.exit("check_static: cppcheck not found (Debian package cppcheck)")
    work = build / "cppcheck"
    work.mkdir(parents=True, exist_ok=True)
    r = subprocess.run(
        [exe, *CPPCHECK_ARGS, f"--cppcheck-build-dir={work}", *CPPCHECK_PATHS], capture_output=True, text=True, cwd=ROOT
    )
    return sorted({line for line in (r.stdout + r.stderr).splitlines() if ": cppcheck: " in line})


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build", type=Path, required=True, help="build folder with compile_commands.json")
    ap.add_argument("--jobs", type=int, default=2, help="clang-tidy processes at once")
    ap.add_argument("--tool", choices=["all", "clang-tidy", "cppcheck"], default="all")
    ap.add_argument("--only", default="", help="clang-tidy: only the units whose path matches this regex")
    args = ap.parse_args()
    build = args.build.resolve()
    findings: list[str] = []
    for tool, fn in (
        ("clang-tidy", lambda: run_clang_tidy(build, args.jobs, args.only)),
        ("cppcheck", lambda: run_cppcheck(build)),
    ):
        if args.tool not in ("all", tool):
            continue
        t0 = time.monotonic()
        got = fn()
        print(f"{tool}: {len(got)} finding(s) in {time.monotonic() - t0:.0f} s", flush=True)
        findings += got
    for f in findings:
        print(f)
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main())
