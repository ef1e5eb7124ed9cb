#!/usr/bin/env python3
"""Checks the flight code's include graph against fsw/layers.txt.

Every quoted #include of a file under fsw/ must resolve to a file of the
repository, stay within its own layer or reach a lower one (never a peer on
the same line, never a higher one), and the graph of files must have no
cycle. Prints each violation and exits 1; exits 0 with a summary otherwise.

    check_layers.py [--root REPO]
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.MULTILINE)


def read_layers(path: Path) -> dict[str, int]:
    """Layer name -> rank (line index among the non-comment lines)."""
    rank: dict[str, int] = {}
    lines = [ln.split("#", 1)[0].split() for ln in path.read_text().splitlines()]
    for i, names in enumerate(ln for ln in lines if ln):
        for name in names:
            rank[name] = i
    return rank


def layer_of(rel: Path) -> str | None:
    """The layer a file under fsw/ belongs to (None: not in a layer folder)."""
    parts = rel.parts
    if parts[:3] == ("fsw", "include", "fsw") and len(parts) > 4:
        return parts[3]
    if parts[:2] == ("fsw", "src") and len(parts) > 3:
        return parts[2]
    if parts[0] == "fsw" and len(parts) > 2 and parts[1] not in ("include", "src"):
        return parts[1]
    return None


def resolve(root: Path, src: Path, inc: str) -> Path | None:
    """The repository file a quoted include names, or None."""
    candidates = [src.parent / inc, root / "fsw/include" / inc, root / "fsw/vision/include" / inc]
    for c in candidates:
        if c.is_file():
            return c.resolve().relative_to(root)
    return None


def check(root: Path) -> list[str]:
    root = root.resolve()
    rank = read_layers(root / "fsw/layers.txt")
    files = sorted(p for p in (root / "fsw").rglob("*") if p.suffix in (".hpp", ".cpp", ".h"))
    errors: list[str] = []
    graph: dict[Path, list[Path]] = {}
    for f in files:
        rel = f.relative_to(root)
        own = layer_of(rel)
        if own is None or own not in rank:
            errors.append(f"{rel}: not in a layer folder listed in fsw/layers.txt")
            continue
        graph[rel] = []
        for inc in INCLUDE.findall(f.read_text()):
            target = resolve(root, f, inc)
            if target is None:
                errors.append(f'{rel}: #include "{inc}" names no file of the repository')
                continue
            graph[rel].append(target)
            other = layer_of(target)
            if other is None or other not in rank:
                errors.append(f'{rel}: #include "{inc}" reaches {target}, outside the layers')
            elif other != own and rank[other] >= rank[own]:
                kind = "a peer" if rank[other] == rank[own] else "a higher"
                errors.append(f'{rel} ({own}): #include "{inc}" reaches {kind} layer ({other})')
    errors += [f"include cycle: {' -> '.join(map(str, c))}" for c in cycles(graph)]
    return errors


def cycles(graph: dict[Path, list[Path]]) -> list[list[Path]]:
    """One cycle per back edge found by a depth-first search."""
    state: dict[Path, int] = {}  # 1: on the stack, 2: done
    stack: list[Path] = []
    found: list[list[Path]] = []

    def visit(n: Path) -> None:
        state[n] = 1
        stack.append(n)
        for m in graph.get(n, []):
            if state.get(m) == 1:
                found.append(stack[stack.index(m) :] + [m])
            elif m not in state:
                visit(m)
        stack.pop()
        state[n] = 2

    for n in sorted(graph):
        if n not in state:
            visit(n)
    return found


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--root",
        type=Path,
        default=Path(__file__).resolve().parents[2],
        help="repository root (default: this script's)",
    )
    args = ap.parse_args(argv)
    errors = check(args.root)
    for e in errors:
        print(e, file=sys.stderr)
    if errors:
        print(f"{len(errors)} layering violation(s)", file=sys.stderr)
        return 1
    print("fsw include graph: layers respected, no cycle")
    return 0


if __name__ == "__main__":
    sys.exit(main())
