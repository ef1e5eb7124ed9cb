#!/usr/bin/env python3
"""Checks that the C++ sources are formatted as .clang-format says.

Runs `clang-format --dry-run -Werror` over every .cpp and .hpp under fsw/,
bindings/, tests/cpp/, tests/fuzz/, tests/cmake/, benchmarks/ and
firmware/; prints clang-format's complaints and exits 1 when a file would
change. The style was applied with clang-format 14 (Debian bookworm's);
another major version formats some constructs differently, so with one the
check is skipped (exit 77, ctest's SKIP_RETURN_CODE).

    check_format.py [--clang-format PATH] [--root REPO]
    check_format.py --fix     (reformat the files in place)
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
from pathlib import Path

FOLDERS = ("fsw", "bindings", "tests/cpp", "tests/fuzz", "tests/cmake", "benchmarks", "firmware")
MAJOR = 14
SKIP = 77


def sources(root: Path) -> list[Path]:
    found: list[Path] = []
    for folder in FOLDERS:
        found += [p for p in (root / folder).rglob("*") if p.suffix in (".cpp", ".hpp") and p.is_file()]
    return sorted(found)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clang-format", default="clang-format", help="clang-format executable")
    ap.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[2], help="repository root")
    ap.add_argument("--fix", action="store_true", help="format the files in place")
    args = ap.parse_args(argv)
    try:
        version = subprocess.run([args.clang_format, "--version"], capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError) as e:
        print(f"{args.clang_format}: cannot run ({e})", file=sys.stderr)
        return 1
    m = re.search(r"version (\d+)\.", version)
    if not m or int(m.group(1)) != MAJOR:
        print(f"skipped: the style is clang-format {MAJOR}'s, this is {version.strip()}")
        return SKIP
    files = sources(args.root)
    mode = ["-i"] if args.fix else ["--dry-run", "-Werror"]
    res = subprocess.run([args.clang_format, *mode, *map(str, files)], capture_output=True, text=True)
    sys.stderr.write(res.stderr)
    if res.returncode != 0:
        print(f"{len(files)} files checked: some are not formatted (fix: {Path(__file__).name} --fix)", file=sys.stderr)
        return 1
    print(f"{len(files)} files formatted as .clang-format says")
    return 0


if __name__ == "__main__":
    sys.exit(main())
