#!/usr/bin/env python3
"""Line and branch coverage of fsw/ from a build with gcov counters
(CMakePresets.json "coverage"; docs/ASSURANCE.md), read with gcovr once and
reported for the flight core, vision and the platform apart. Fails (exit 1)
when the core is under its floors or when an exclusion matches no line;
prints what is left uncovered in the core, file by file.

    coverage.py --build BUILD [--root SRC] [--gcovr PATH] [--json OUT] [--exclusions FILE]

--root is the path the build was configured with when it is not this
checkout's own (the Makefile builds the tree at a fixed path, its sources
reached through a fixed symbolic link to the checkout); the counters name
their sources by that path.

How lines and branches are counted:
- A source line is covered when any instantiation of its template runs it,
  and a branch of a line is taken when any instantiation takes it (gcovr
  --merge-lines, the count of a source-level tool such as lcov). The core's
  templates are compiled for double and float and the modal classes at
  3, 10 and 50 modes: counting every instantiation's copy of a line apart
  would ask every test to be repeated at every size. The figures per
  instantiation are printed too, for information.
- Branches of exception paths (--exclude-throw-branches: the core has no
  exceptions; those are the test harness's standard library calls) and
  branches the compiler leaves on lines without code
  (--exclude-unreachable-branches) are not counted.
- tests/static/coverage_exclusions.txt lists the lines (or a line's
  branches) that no test can sensibly reach, each with its reason; they are
  not counted, and the script fails when one no longer matches a line.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
EXCLUSIONS = Path(__file__).resolve().parent / "coverage_exclusions.txt"

# The parts and their filters (paths relative to the repository); the floors
# apply to the core.
PARTS = {
    "core": r"fsw/(include|src)/",
    "vision": r"fsw/vision/",
    "platform": r"fsw/platform/",
}
CORE_PREFIXES = ("fsw/include/", "fsw/src/")
FLOORS = {"core": {"line": 95.0, "branch": 85.0}}
KINDS = ("line", "branches")


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


def read_exclusions(path: Path) -> list[dict]:
    """Entries `file | kind | source line | reason` (kind: line or
    branches; the source line as written, leading and trailing blanks
    ignored; every line of the file that reads so is excluded). A source
    line written `anchor >> line` is the first line reading `line` after
    each line reading `anchor`, for text that occurs more than once."""
    out = []
    for n, raw in enumerate(path.read_text().splitlines(), 1):
        text = raw.strip()
        if not text or text.startswith("#"):
            continue
        parts = [p.strip() for p in text.split(" | ")]
        if len(parts) != 4 or parts[1] not in KINDS or not all(parts):
            raise SystemExit(f"{path.name}:{n}: want `file | line|branches | source line | reason`: {text}")
        out.append({"file": parts[0], "kind": parts[1], "source": parts[2], "reason": parts[3], "at": n})
    return out


def matching_lines(lines: list[str], source: str) -> set[int]:
    """1-based numbers of the lines an exclusion's source text names."""
    text = [s.strip() for s in lines]
    anchor, sep, target = source.partition(" >> ")
    if not sep:
        return {i for i, s in enumerate(text, 1) if s == source}
    out = set()
    for a, s in enumerate(text):
        if s != anchor:
            continue
        for i in range(a + 1, len(text)):
            if text[i] == target:
                out.add(i + 1)
                break
    return out


def apply_exclusions(data: dict, exclusions: list[dict]) -> list[str]:
    """Drops the excluded lines (or their branches) from gcovr's JSON in
    place; returns a problem for each exclusion that matches nothing."""
    by_file = {f["file"]: f for f in data["files"]}
    problems = []
    for ex in exclusions:
        src = ROOT / ex["file"]
        if not src.is_file():
            problems.append(f"exclusion line {ex['at']}: no file {ex['file']}")
            continue
        numbers = matching_lines(src.read_text().splitlines(), ex["source"])
        f = by_file.get(ex["file"])
        hit = [ln for ln in f["lines"] if ln["line_number"] in numbers] if f else []
        if not hit:
            problems.append(f"exclusion line {ex['at']}: {ex['file']}: no counted line `{ex['source']}`")
            continue
        if ex["kind"] == "line":
            f["lines"] = [ln for ln in f["lines"] if ln["line_number"] not in numbers]
        else:
            if not any(ln.get("branches") for ln in hit):
                problems.append(f"exclusion line {ex['at']}: {ex['file']}: no counted branch on `{ex['source']}`")
            for ln in hit:
                ln["branches"] = []
    return problems


def merged(f: dict) -> tuple[list[int], dict[int, tuple[int, int]]]:
    """A file's uncovered source lines and, per line, its branches
    (taken, total), every instantiation of a line merged as gcovr's
    --merge-lines does (a branch by its number)."""
    count: dict[int, int] = defaultdict(int)
    branches: dict[int, dict[int, int]] = defaultdict(dict)
    for ln in f["lines"]:
        if ln.get("gcovr/noncode"):
            continue
        no = ln["line_number"]
        count[no] += ln["count"]
        for i, b in enumerate(ln.get("branches", [])):
            key = b.get("branchno", i)
            branches[no][key] = branches[no].get(key, 0) + b["count"]
    missed = sorted(no for no, c in count.items() if c == 0)
    part = {no: (sum(1 for c in bs.values() if c > 0), len(bs)) for no, bs in branches.items() if bs}
    return missed, part


def summary(gcovr: str, root: Path, tracefile: Path, filt: str, out: Path, merge: bool) -> dict:
    cmd = [gcovr, "-r", str(root), "-a", str(tracefile), "--filter", filt, "--json-summary", str(out)]
    if merge:
        cmd.append("--merge-lines")
    subprocess.run(cmd, check=True, cwd=root, stdout=subprocess.DEVNULL)
    return json.loads(out.read_text())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build", type=Path, required=True)
    ap.add_argument("--root", type=Path, default=ROOT, help="the source path the build was configured with")
    ap.add_argument("--gcovr", default="gcovr")
    ap.add_argument("--json", type=Path, help="write the figures here")
    ap.add_argument("--exclusions", type=Path, default=EXCLUSIONS)
    args = ap.parse_args()
    build = args.build.resolve()
    full = build / "coverage-full.json"
    # One pass of gcov over every counter file.
    common = ["--exclude-throw-branches", "--exclude-unreachable-branches", "--gcov-ignore-parse-errors=all"]
    subprocess.run(
        [
            args.gcovr,
            "-r",
            str(args.root),
            "--object-directory",
            str(build),
            "--filter",
            "fsw/",
            *common,
            "--json",
            str(full),
            "-j",
            "2",
            # Counter files only from this build (not from any tree under --root).
            str(build),
        ],
        check=True,
        cwd=args.root,
    )
    data = json.loads(full.read_text())
    exclusions = read_exclusions(args.exclusions)
    problems = apply_exclusions(data, exclusions)
    counted = build / "coverage-counted.json"
    counted.write_text(json.dumps(data))

    figures: dict = {"exclusions": len(exclusions)}
    failed = list(problems)
    for part, filt in PARTS.items():
        s = summary(args.gcovr, args.root, counted, filt, build / f"coverage-{part}.json", merge=True)
        r = summary(args.gcovr, args.root, counted, filt, build / f"coverage-{part}-instances.json", merge=False)
        figures[part] = {
            "lines": [s["line_covered"], s["line_total"], s["line_percent"]],
            "branches": [s["branch_covered"], s["branch_total"], s["branch_percent"]],
            "per_instantiation": {
                "lines": [r["line_covered"], r["line_total"], r["line_percent"]],
                "branches": [r["branch_covered"], r["branch_total"], r["branch_percent"]],
            },
        }
        print(
            f"{part:9s} lines {s['line_covered']:6d} / {s['line_total']:6d} = {s['line_percent']:5.1f} %   "
            f"branches {s['branch_covered']:6d} / {s['branch_total']:6d} = {s['branch_percent']:5.1f} %   "
            f"(per instantiation: {r['line_percent']:5.1f} % / {r['branch_percent']:5.1f} %)"
        )
        floor = FLOORS.get(part)
        if floor:
            if s["line_percent"] < floor["line"]:
                failed.append(f"{part}: lines {s['line_percent']} % < {floor['line']} %")
            if s["branch_percent"] < floor["branch"]:
                failed.append(f"{part}: branches {s['branch_percent']} % < {floor['branch']} %")
    print(f"excluded with their reasons ({args.exclusions.name}): {len(exclusions)} entries")
    print("left in the core (uncovered lines; lines with branches not taken, taken/total):")
    for f in sorted(data["files"], key=lambda f: f["file"]):
        if not f["file"].startswith(CORE_PREFIXES):
            continue
        missed, br = merged(f)
        partial = [f"{no} ({t}/{n})" for no, (t, n) in sorted(br.items()) if t < n]
        if missed or partial:
            print(f"  {f['file']}")
            if missed:
                print(f"    lines: {_ranges(missed)}")
            if partial:
                print(f"    branches: {', '.join(partial)}")
    if args.json:
        args.json.write_text(json.dumps(figures, indent=1) + "\n")
    for msg in failed:
        print(f"coverage: {msg}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
