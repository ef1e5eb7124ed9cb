"""Every reference in the documents and the code resolves.

- A relative markdown link `[text](path#anchor)` points at a file that
  exists and, with an anchor, at one of that file's headings.
- A `docs/...md` path named anywhere (documents, Python, C++, CMake) exists,
  and a section quoted right after it (`docs/GAP.md, "Quantify"`) begins a
  heading of that document.
- Every document is listed in docs/README.md; every dated record in
  docs/results/ is named `YYYY-MM-DD-topic.md`, opens with the records'
  header and is listed in docs/results/README.md.
- Nothing names a file outside the repository, and nothing cites an issue
  number or a numbered seed label: papers are cited by title and authors.
"""

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
THIS = Path(__file__).resolve()
TEXT_SUFFIXES = {
    ".md",
    ".py",
    ".cpp",
    ".hpp",
    ".h",
    ".c",
    ".txt",
    ".cmake",
    ".toml",
    ".sh",
    ".ld",
    ".in",
    ".yml",
    ".yaml",
    ".cfg",
    ".ini",
}
TEXT_NAMES = {"Makefile", "run", ".clang-format", ".gitignore"}
SKIP_DIRS = {".git", ".venv", "build", "report", "__pycache__", ".pytest_cache", ".ruff_cache"}

LINK = re.compile(r"!?\[[^\]\n]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
DOC_PATH = re.compile(r"(?<![\w./-])(docs/\w[\w./-]*?\.md)\b")
# a section quoted right after a document's path: docs/X.md, "Heading" or `docs/X.md` "Heading"
DOC_SECTION = re.compile(r"(?<![\w./-])(docs/\w[\w./-]*?\.md)`?,?[ \t]*(?:\n[ \t]*(?:#|//)?[ \t]*)?\"([^\"]{1,120})\"")
FENCE = re.compile(r"^[ \t]*```.*?^[ \t]*```[ \t]*$", re.M | re.S)
INLINE_CODE = re.compile(r"`[^`\n]*`")
OUTSIDE = {
    "a path into a sibling folder": re.compile(r"\.\./shared"),
    "a design document outside the repository": re.compile(r"\bDESIGN\.md\b"),
    "a style guide outside the repository": re.compile(r"\bSTYLE\.md\b"),
    "a folder of source papers outside the repository": re.compile(r"(?<![\w.-])seeds/"),
    "an issue number": re.compile(r"\bissues?[ \t]*[#-]?[ \t]*\d+", re.I),
    "a numbered seed label instead of the paper's title": re.compile(r"\bseed[ \t-]*0\d\d\b", re.I),
}
RECORD_NAME = re.compile(r"^\d{4}-\d{2}-\d{2}-[a-z0-9]+(?:-[a-z0-9]+)*\.md$")
RECORD_HEADER = ("Question", "Command", "Commit", "Machine", "Wall time")


def _tracked_files() -> list:
    try:
        out = subprocess.run(
            ["git", "ls-files", "--cached", "--others", "--exclude-standard"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.splitlines()
        paths = [ROOT / p for p in out]
    except (OSError, subprocess.CalledProcessError):  # not a git checkout: walk the tree
        paths = [
            p
            for p in ROOT.rglob("*")
            if not any(part in SKIP_DIRS or part.startswith("build") for part in p.relative_to(ROOT).parts)
        ]
    return sorted(p for p in paths if p.is_file() and (p.suffix in TEXT_SUFFIXES or p.name in TEXT_NAMES))


def _markdown(files) -> list:
    return [p for p in files if p.suffix == ".md"]


def _prose(text: str) -> str:
    """Markdown without its fenced code blocks (a heading or a link there is not one)."""
    return FENCE.sub("", text)


def _slug(heading: str) -> str:
    """The anchor a markdown renderer gives a heading (GitHub's rule)."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def _headings(md: Path) -> list:
    return [m.group(1).strip() for m in re.finditer(r"^#{1,6}[ \t]+(.+?)[ \t#]*$", _prose(md.read_text()), re.M)]


def _anchors(md: Path) -> set:
    seen, out = {}, set()
    for h in _headings(md):
        s = _slug(h)
        n = seen.get(s, 0)
        seen[s] = n + 1
        out.add(s if n == 0 else f"{s}-{n}")
    return out


def _sections(md: Path) -> list:
    """What a quoted section name may begin: a heading, or the first line of a
    paragraph or list item that opens with its name ("Segmentation. Only ...")."""
    lines = _prose(md.read_text()).splitlines()
    leads = [line for prev, line in zip([""] + lines, lines) if not prev.strip() and line.strip()]
    items = [re.sub(r"^\s*[-*]\s+", "", line) for line in lines if re.match(r"^\s*[-*]\s+\S", line)]
    return _headings(md) + leads + items


def _plain(s: str) -> str:
    return " ".join(re.sub(r"[`*_]", "", s).lower().split())


def broken_links(md: Path) -> list:
    """The relative links of one markdown file that do not resolve."""
    bad = []
    text = INLINE_CODE.sub("", _prose(md.read_text()))
    for m in LINK.finditer(text):
        target = m.group(1)
        if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I):  # http:, https:, mailto:
            continue
        path, _, anchor = target.partition("#")
        dest = (md.parent / path).resolve() if path else md
        if not dest.exists():
            bad.append(f"{md.relative_to(ROOT)}: link to {target}: no such file")
        elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
            bad.append(f"{md.relative_to(ROOT)}: link to {target}: no heading with that anchor")
    return bad


def broken_doc_paths(f: Path) -> list:
    """The docs/...md paths (and the sections quoted after them) named in one file that do not resolve."""
    text = f.read_text(errors="replace")
    bad = []
    for m in DOC_PATH.finditer(text):
        if not (ROOT / m.group(1)).is_file():
            bad.append(f"{f.relative_to(ROOT)}: names {m.group(1)}: no such file")
    for m in DOC_SECTION.finditer(text):
        doc = ROOT / m.group(1)
        if doc.is_file():
            quoted = _plain(re.sub(r"\n[ \t]*(#|//)?", " ", m.group(2)))
            if not any(_plain(h).startswith(quoted) for h in _sections(doc)):
                bad.append(f'{f.relative_to(ROOT)}: names section "{m.group(2)}" of {m.group(1)}: no such heading')
    return bad


def outside_names(f: Path) -> list:
    bad = []
    for n, line in enumerate(f.read_text(errors="replace").splitlines(), 1):
        for what, rx in OUTSIDE.items():
            if rx.search(line):
                bad.append(f"{f.relative_to(ROOT)}:{n}: {what}: {line.strip()}")
    return bad


@pytest.fixture(scope="module")
def files():
    return _tracked_files()


def test_relative_markdown_links_resolve(files):
    bad = [b for md in _markdown(files) for b in broken_links(md)]
    assert not bad, "\n".join(bad)


def test_named_documents_and_sections_exist(files):
    bad = [b for f in files if f.resolve() != THIS for b in broken_doc_paths(f)]
    assert not bad, "\n".join(bad)


def test_nothing_names_files_outside_the_repository_or_issue_and_seed_numbers(files):
    bad = [b for f in files if f.resolve() != THIS for b in outside_names(f)]
    assert not bad, "\n".join(bad)


def test_every_document_is_in_the_docs_index(files):
    index = ROOT / "docs" / "README.md"
    linked = {(index.parent / m.group(1).partition("#")[0]).resolve() for m in LINK.finditer(_prose(index.read_text()))}
    docs = [
        p
        for p in _markdown(files)
        if p.is_relative_to(ROOT / "docs") and p != index and p.parent != ROOT / "docs" / "results"
    ]
    missing = [str(p.relative_to(ROOT)) for p in docs if p.resolve() not in linked]
    assert (ROOT / "docs" / "results" / "README.md").resolve() in linked, "docs/README.md must link the results index"
    assert not missing, "documents missing from docs/README.md: " + ", ".join(missing)


def test_results_are_dated_records_listed_in_their_index():
    folder = ROOT / "docs" / "results"
    index = folder / "README.md"
    linked = {m.group(1).partition("#")[0] for m in LINK.finditer(_prose(index.read_text()))}
    bad = []
    for rec in sorted(folder.glob("*.md")):
        if rec == index:
            continue
        if not RECORD_NAME.match(rec.name):
            bad.append(f"{rec.name}: not named YYYY-MM-DD-topic.md")
        text = _prose(rec.read_text())
        header = text[: text.find("\n## ")] if "\n## " in text else text
        fields = re.findall(r"^\*\*(Question|Commands?|Commit|Machine|Wall time)\.\*\*", header, re.M)
        if tuple(f.rstrip("s") if f.startswith("Command") else f for f in fields) != RECORD_HEADER:
            bad.append(
                f"{rec.name}: header fields {fields}, expected {list(RECORD_HEADER)} in that order "
                "before the first '## ' section"
            )
        if rec.name not in linked:
            bad.append(f"{rec.name}: not listed in docs/results/README.md")
    assert not bad, "\n".join(bad)


def test_the_checks_catch_a_broken_reference(tmp_path, monkeypatch):
    """Each check fails on the mistake it is there for."""
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "A.md").write_text("# A\n\n## Only section\n")
    md = tmp_path / "docs" / "B.md"
    md.write_text("[ok](A.md#only-section) [gone](C.md) [no anchor](A.md#elsewhere)\n```\n[in code](D.md)\n```\n")
    assert broken_links(md) == [
        "docs/B.md: link to C.md: no such file",
        "docs/B.md: link to A.md#elsewhere: no heading with that anchor",
    ]
    src = tmp_path / "x.py"
    src.write_text('# see docs/A.md, "Only section"; docs/A.md, "Missing"; docs/Z.md\n')
    assert broken_doc_paths(src) == [
        "x.py: names docs/Z.md: no such file",
        'x.py: names section "Missing" of docs/A.md: no such heading',
    ]
    src.write_text("# as " + "DESIGN" + ".md says; fixed in " + "issue" + " 12; see " + "Seed" + " 003\n")
    assert [b.split(": ")[1] for b in outside_names(src)] == [
        "a design document outside the repository",
        "an issue number",
        "a numbered seed label instead of the paper's title",
    ]
