"""The Python side passes its linter (ruff, configured in pyproject.toml:
pyflakes, syntax errors, bugbear's likely bugs and sorted imports), is
formatted by ruff's formatter, and its functions are short."""

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _ruff() -> list:
    exe = shutil.which("ruff") or str(Path(sys.executable).with_name("ruff"))
    if not Path(exe).exists():
        pytest.fail("ruff is not installed (pip install -e .[dev])")
    return [exe]


def test_ruff_finds_nothing():
    r = subprocess.run(
        _ruff() + ["check", "--no-cache", "bench", "hil_sim", "tests/py", "examples"],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stdout + r.stderr


def test_python_is_formatted():
    r = subprocess.run(
        _ruff() + ["format", "--check", "--no-cache", "."],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, "not formatted (run `ruff format .`):\n" + r.stdout + r.stderr


def test_ruff_format_check_would_catch_an_unformatted_file(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("x = {  'a':1 }\n")
    r = subprocess.run(
        _ruff() + ["format", "--check", "--no-cache", "--config", str(ROOT / "pyproject.toml"), str(bad)],
        capture_output=True,
        text=True,
    )
    assert r.returncode != 0 and "bad.py" in r.stdout


def test_ruff_would_catch_an_unused_import(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("import os\n")
    r = subprocess.run(
        _ruff() + ["check", "--no-cache", "--config", str(ROOT / "pyproject.toml"), str(bad)],
        capture_output=True,
        text=True,
    )
    assert r.returncode != 0 and "F401" in r.stdout


# No function of the bench or the HIL loop is longer than this many lines
# (from its def to its last line, nested functions counted in their parent).
MAX_FUNCTION_LINES = 80
# Longer ones not yet split, at their length today: they may shrink, not
# grow (none left; an entry fails the test once its function is short).
LONG_FUNCTIONS: dict = {}


def function_lengths(source: str, where: str) -> dict:
    """{"<where>:<qualified name>": lines} of every function in ``source``."""
    out = {}

    def visit(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                name = prefix + child.name
                if not isinstance(child, ast.ClassDef):
                    out[f"{where}:{name}"] = child.end_lineno - child.lineno + 1
                visit(child, name + ".")
            else:
                visit(child, prefix)

    visit(ast.parse(source), "")
    return out


def _project_function_lengths() -> dict:
    out = {}
    for path in sorted([*(ROOT / "bench").rglob("*.py"), *(ROOT / "hil_sim").rglob("*.py")]):
        out.update(function_lengths(path.read_text(), path.relative_to(ROOT).as_posix()))
    return out


def test_functions_are_short():
    lengths = _project_function_lengths()
    bad = [
        f"{name}: {n} lines (at most {LONG_FUNCTIONS.get(name, MAX_FUNCTION_LINES)})"
        for name, n in sorted(lengths.items())
        if n > LONG_FUNCTIONS.get(name, MAX_FUNCTION_LINES)
    ]
    assert not bad, "functions too long (split them by concept):\n" + "\n".join(bad)
    done = [
        f"{name}: {lengths.get(name, 'gone')}" for name in LONG_FUNCTIONS if lengths.get(name, 0) <= MAX_FUNCTION_LINES
    ]
    assert not done, "short now or gone: remove from LONG_FUNCTIONS:\n" + "\n".join(done)


def test_function_length_counts_nested_functions_and_methods():
    body = "\n".join(f"        x{i} = {i}" for i in range(78))
    src = f"class A:\n    def f(self):\n        def g():\n            pass\n{body}\n\n\ndef h():\n    pass\n"
    n = function_lengths(src, "m.py")
    assert n == {"m.py:A.f": 81, "m.py:A.f.g": 2, "m.py:h": 2}
    assert n["m.py:A.f"] > MAX_FUNCTION_LINES
