"""The Python side passes its linter (ruff, configured in pyproject.toml:
pyflakes, syntax errors and bugbear's likely bugs)."""
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
    r = subprocess.run(_ruff() + ["check", "--no-cache", "bench", "hil_sim", "tests/py", "examples"], cwd=ROOT,
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr


def test_ruff_would_catch_an_unused_import(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("import os\n")
    r = subprocess.run(_ruff() + ["check", "--no-cache", "--config", str(ROOT / "pyproject.toml"), str(bad)],
                       capture_output=True, text=True)
    assert r.returncode != 0 and "F401" in r.stdout
