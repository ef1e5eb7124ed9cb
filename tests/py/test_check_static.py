"""The static-analysis script's memory of clean units (tests/static/check_static.py):
a unit is analysed again whenever anything clang-tidy reads changes, a
suppression comment included, and only then."""

from __future__ import annotations

import importlib.util
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("check_static", ROOT / "tests/static/check_static.py")
check_static = importlib.util.module_from_spec(spec)
spec.loader.exec_module(check_static)

pytestmark = pytest.mark.skipif(shutil.which("c++") is None, reason="needs a C++ compiler")


def _key(tmp_path: Path, unit: str, header: str, flags: str = "-O2") -> str:
    (tmp_path / "unit.cpp").write_text(unit)
    (tmp_path / "unit.hpp").write_text(header)
    entry = {
        "directory": str(tmp_path),
        "command": f"c++ {flags} -std=c++17 -I{tmp_path} -o unit.o -c {tmp_path / 'unit.cpp'}",
        "file": str(tmp_path / "unit.cpp"),
    }
    return check_static._unit_key(entry, "clang-tidy 14 + checks")


def test_a_unit_is_analysed_again_when_anything_it_reads_changes(tmp_path):
    unit = '#include "unit.hpp"\nint f(int x) { return g(x); }\n'
    header = "inline int g(int x) { return 2 * x; }\n"
    base = _key(tmp_path, unit, header)
    assert base == _key(tmp_path, unit, header)  # nothing changed: remembered
    suppressed = "inline int g(int x) { return 2 * x; }  // NOLINT(bugprone-foo): reason\n"
    changed = {
        "header code": _key(tmp_path, unit, "inline int g(int x) { return 3 * x; }\n"),
        "a suppression in a header": _key(tmp_path, unit, suppressed),
        "the unit": _key(tmp_path, unit + "// NOLINTNEXTLINE\n", header),
        "the compile flags": _key(tmp_path, unit, header, "-O0"),
    }
    for what, key in changed.items():
        assert key is not None and key != base, what
    assert check_static._unit_key({**_entry(tmp_path), "command": "c++ -c missing.cpp -o m.o"}, "") is None


def _entry(tmp_path: Path) -> dict:
    return {"directory": str(tmp_path), "file": str(tmp_path / "missing.cpp")}
