"""Every third-party module the installed packages import is provided by a
distribution that pyproject.toml lists: a clean install must be able to run
them."""

from __future__ import annotations

import ast
import importlib.metadata as md
import re
import sys
from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib")  # Python 3.11+ (sys.stdlib_module_names: 3.10+)

ROOT = Path(__file__).resolve().parents[2]
LOCAL = {"bench", "hil_sim", "fsw_bindings"}  # this project's own packages and native module


def _imported_top_level(paths) -> dict:
    found: dict = {}
    for path in paths:
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for n in names:
                found.setdefault(n.split(".")[0], str(path.relative_to(ROOT)))
    return found


def _listed_distributions(extra=None) -> set:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = list(project["dependencies"]) + (list(project["optional-dependencies"][extra]) if extra else [])
    return {re.split(r"[<>=!~;\[ ]", r, maxsplit=1)[0].strip().lower().replace("_", "-") for r in reqs}


def test_every_third_party_import_is_a_listed_dependency():
    sources = sorted((ROOT / "hil_sim").glob("*.py")) + sorted((ROOT / "bench").rglob("*.py"))
    # The comparison benchmarks (bench/perf/perf_*.py) may use the dev extra, the
    # Basilisk engine (bench/basilisk_*.py) the basilisk extra.
    runtime = [p for p in sources if not p.name.startswith(("perf_", "basilisk_"))]
    perf = [p for p in sources if p.name.startswith("perf_")]
    bsk = [p for p in sources if p.name.startswith("basilisk_")]
    by_module = md.packages_distributions()
    missing = []
    for files, listed in (
        (runtime, _listed_distributions()),
        (perf, _listed_distributions("dev")),
        (bsk, _listed_distributions("basilisk")),
    ):
        missing += _unlisted(_imported_top_level(files), listed, by_module)
    assert not missing, "imported but not in pyproject.toml dependencies: " + "; ".join(missing)


def _unlisted(imported: dict, listed: set, by_module) -> list:
    third_party = {m: f for m, f in imported.items() if m not in sys.stdlib_module_names and m not in LOCAL}
    missing = []
    for module, where in sorted(third_party.items()):
        dists = {d.lower().replace("_", "-") for d in by_module.get(module, [])}
        if not dists & listed:
            missing.append(f"{module} (imported by {where}; distributions {sorted(dists) or 'none installed'})")
    return missing


def test_crc_matches_the_reference_package():
    from hil_sim import packets as P

    assert P.crc16(b"123456789") == P.CRC16_CHECK
    data = bytes(range(256)) * 3
    for n in (0, 1, 2, 17, 255, 768):
        assert P.crc16(data[:n]) == P.crc16_reference(data[:n])
