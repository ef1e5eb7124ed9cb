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

clang-tidy's verdict on a unit is a function of what it reads: the unit
preprocessed with its comments kept (every header it includes, every NOLINT
in them), its compile command, the checks' configuration and the tool's
version. A unit found clean is remembered under that hash (in
$XDG_CACHE_HOME/proxops/clang-tidy, the checkout's own path taken out so
another clone shares it) and not analysed again until one of those changes;
a unit with findings is always analysed. --no-cache analyses every unit.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import shlex
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

CACHE = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "proxops" / "clang-tidy"

FINDING = re.compile(r"^(?P<path>/[^:]+):(?P<line>\d+):\d+: (?P<kind>warning|error): (?P<msg>.*)$")


def _rel(path: str) -> str:
    p = Path(path).resolve()
    try:
        return str(p.relative_to(ROOT))
    except ValueError:
        return str(p)


def _unit_key(entry: dict, salt: str) -> str | None:
    """The hash of what clang-tidy reads for one unit (module docstring), or
    None when the unit does not preprocess."""
    args = shlex.split(entry["command"]) if "command" in entry else list(entry["arguments"])
    keep, skip = [], False
    for a in args:
        if skip:
            skip = False
        elif a == "-o":
            skip = True
        elif a != "-c":
            keep.append(a)
    r = subprocess.run([*keep, "-E", "-C"], capture_output=True, text=True, cwd=entry["directory"])
    if r.returncode != 0:
        return None
    root = str(ROOT)
    h = hashlib.sha256()
    for part in (salt, " ".join(keep), r.stdout):
        h.update(part.replace(root, "<root>").encode())
    return h.hexdigest()


def run_clang_tidy(build: Path, jobs: int, only: str = "", use_cache: bool = True) -> list[str]:
    exe = shutil.which("clang-tidy-14") or shutil.which("clang-tidy")
    if exe is None:
        sys.exit("check_static: clang-tidy not found (Debian package clang-tidy)")
    db = json.loads((build / "compile_commands.json").read_text())
    units = sorted({e["file"] for e in db if Path(e["file"]).resolve().is_relative_to(FSW)})
    units = [u for u in units if re.search(only, _rel(u))]
    if not units:
        sys.exit(f"check_static: no translation unit under fsw/ in {build}/compile_commands.json")

    version = subprocess.run([exe, "--version"], capture_output=True, text=True).stdout
    config = "".join(p.read_text() for p in sorted(FSW.rglob(".clang-tidy")))
    entries = {e["file"]: e for e in db}

    def one(unit: str) -> tuple[str, str, float]:
        t0 = time.monotonic()
        key = _unit_key(entries[unit], version + config) if use_cache else None
        if key is not None and (CACHE / key).is_file():
            return unit, "", 0.0
        r = subprocess.run([exe, "-p", str(build), "--quiet", unit], capture_output=True, text=True, cwd=ROOT)
        out = r.stdout + r.stderr
        if key is not None and r.returncode == 0 and not any(FINDING.match(x) for x in out.splitlines()):
            CACHE.mkdir(parents=True, exist_ok=True)
            (CACHE / key).write_text(_rel(unit) + "\n")
        return unit, out, time.monotonic() - t0

    found: set[str] = set()
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        for unit, out, dt in pool.map(one, units):
            new = set()
            for line in out.splitlines():
                m = FINDING.match(line)
                if m and Path(m["path"]).resolve().is_relative_to(FSW):
                    new.add(f"{_rel(m['path'])}:{m['line']}: clang-tidy: {m['msg']}")
            took = f"{dt:.0f} s" if dt > 0 else "clean before, unchanged"
            print(f"  clang-tidy {_rel(unit)}: {took}, {len(new - found)} new finding(s)", flush=True)
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
    ap.add_argument("--no-cache", action="store_true", help="clang-tidy: analyse every unit, even one clean before")
    args = ap.parse_args()
    build = args.build.resolve()
    findings: list[str] = []
    for tool, fn in (
        ("clang-tidy", lambda: run_clang_tidy(build, args.jobs, args.only, not args.no_cache)),
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
