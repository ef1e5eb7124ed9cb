"""docs/REQUIREMENTS.md against the tests: every test a requirement names
exists, every requirement names one, and every flight test (GoogleTest in
tests/cpp, ctest add_test in tests/) is named by a requirement."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "REQUIREMENTS.md"

REQ = re.compile(r"^\*\*(FSW-[A-Z]+-\d\d)\*\*", re.M)
GTEST = re.compile(r"^(?:TEST|TEST_F|TEST_P|TYPED_TEST)\(\s*(\w+)\s*,\s*(\w+)\s*\)", re.M)
CTEST = re.compile(r"add_test\(\s*NAME\s+(\w+)")


def requirements(text: str) -> dict[str, list[str]]:
    """Requirement id -> the tests its "Verified by:" names, in order."""
    out: dict[str, list[str]] = {}
    starts = [(m.start(), m.group(1)) for m in REQ.finditer(text)]
    for i, (pos, rid) in enumerate(starts):
        end = starts[i + 1][0] if i + 1 < len(starts) else len(text)
        block = re.split(r"\n#", text[pos:end])[0]
        assert rid not in out, f"{rid} appears twice"
        _, _, verified = block.partition("Verified by:")
        out[rid] = re.findall(r"`([^`]+)`", verified)
    return out


def _test_sources(folder: str, suffix: str) -> list[Path]:
    """The repository's files under folder ending in suffix: those git
    tracks when this is a git checkout (a file still being written is not
    yet a flight test), else every one."""
    try:
        out = subprocess.run(["git", "ls-files", "-z", "tests"], cwd=ROOT, capture_output=True, check=True).stdout
        files = [ROOT / p for p in out.decode().split("\0") if p]
    except (OSError, subprocess.CalledProcessError):
        files = list((ROOT / "tests").rglob("*"))
    return [f for f in files if f.is_file() and f.name.endswith(suffix) and f.is_relative_to(ROOT / folder)]


def flight_tests() -> tuple[set[tuple[str, str]], set[str]]:
    gtests = set()
    for src in _test_sources("tests/cpp", ".cpp"):
        gtests |= set(GTEST.findall(src.read_text()))
    ctests = set()
    for cm in _test_sources("tests", "CMakeLists.txt"):
        ctests |= set(CTEST.findall(cm.read_text()))
    return gtests, ctests


def problems(text: str) -> list[str]:
    reqs = requirements(text)
    gtests, ctests = flight_tests()
    suites = {s for s, _ in gtests}
    found: list[str] = []
    covered: set[tuple[str, str]] = set()
    named_ctests: set[str] = set()
    if not reqs:
        found.append("no requirement found")
    for rid, refs in reqs.items():
        if not refs:
            found.append(f"{rid}: names no test")
        for ref in refs:
            if "::" in ref:
                path, _, func = ref.partition("::")
                f = ROOT / path
                if not (path.startswith("tests/py/") and f.is_file()):
                    found.append(f"{rid}: {ref}: no such test file")
                elif not re.search(rf"^def {re.escape(func)}\(", f.read_text(), re.M):
                    found.append(f"{rid}: {ref}: no such test in {path}")
            elif "." in ref:
                suite, _, name = ref.partition(".")
                if name == "*":
                    if suite not in suites:
                        found.append(f"{rid}: {ref}: no such GoogleTest suite")
                    covered |= {t for t in gtests if t[0] == suite}
                elif (suite, name) not in gtests:
                    found.append(f"{rid}: {ref}: no such GoogleTest test")
                else:
                    covered.add((suite, name))
            elif ref in ctests:
                named_ctests.add(ref)
            else:
                found.append(f"{rid}: {ref}: no such ctest test")
    for suite, name in sorted(gtests - covered):
        found.append(f"{suite}.{name} ({'tests/cpp'}): named by no requirement")
    for name in sorted(ctests - named_ctests):
        found.append(f"ctest {name}: named by no requirement")
    return found


def test_every_named_test_exists_and_every_flight_test_names_a_requirement():
    assert problems(DOC.read_text()) == []


def test_the_check_finds_a_missing_test_and_an_unnamed_one():
    text = DOC.read_text()
    broken = text.replace("`So3Test.*`", "`So3Test.NoSuchTest`", 1)
    assert broken != text
    found = problems(broken)
    assert any("So3Test.NoSuchTest: no such GoogleTest test" in p for p in found)
    assert any(p.startswith("So3Test.ExpIsUnitQuaternion") and "named by no requirement" in p for p in found)
    assert any(
        "no such test file" in p for p in problems(text + "\n**FSW-X-99** x.\nVerified by: `tests/py/nope.py::t`.\n")
    )
