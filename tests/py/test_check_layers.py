"""The include-graph check of the flight code (tests/cpp/check_layers.py):
it passes on the repository and fails on an upward include, a peer include,
a cycle and a stale path."""

import importlib.util
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("check_layers", ROOT / "tests/cpp/check_layers.py")
check_layers = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(check_layers)


@pytest.fixture
def tree(tmp_path):
    shutil.copytree(ROOT / "fsw", tmp_path / "fsw")
    return tmp_path


def _append_include(path: Path, inc: str) -> None:
    text = path.read_text()
    path.write_text(text.replace("#pragma once\n", f'#pragma once\n#include "{inc}"\n', 1))


def test_repository_respects_layers():
    assert check_layers.check(ROOT) == []


def test_upward_include_fails(tree):
    _append_include(tree / "fsw/include/fsw/math/so3.hpp", "fsw/nav/nav_state.hpp")
    errors = check_layers.check(tree)
    assert any("so3.hpp (math)" in e and "a higher layer (nav)" in e for e in errors)
    assert any(e.startswith("include cycle") for e in errors)  # nav_state includes so3


def test_peer_include_fails(tree):
    _append_include(tree / "fsw/include/fsw/modal/modal_tracker.hpp", "fsw/link/apid.hpp")
    errors = check_layers.check(tree)
    assert errors == [
        'fsw/include/fsw/modal/modal_tracker.hpp (modal): #include "fsw/link/apid.hpp" reaches a peer layer (link)'
    ]


def test_cycle_within_a_layer_fails(tree):
    _append_include(tree / "fsw/include/fsw/link/crc16.hpp", "fsw/link/framer.hpp")
    errors = check_layers.check(tree)
    assert len(errors) == 1 and errors[0].startswith("include cycle: fsw/include/fsw/link/")


def test_stale_path_and_unlisted_folder_fail(tree):
    _append_include(tree / "fsw/include/fsw/math/so3.hpp", "fsw/no_such_header.hpp")
    (tree / "fsw/include/fsw/extra").mkdir()
    (tree / "fsw/include/fsw/extra/x.hpp").write_text("#pragma once\n")
    errors = check_layers.check(tree)
    assert any("names no file" in e for e in errors)
    assert any("extra/x.hpp: not in a layer folder" in e for e in errors)
