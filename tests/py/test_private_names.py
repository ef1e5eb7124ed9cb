"""No module of the bench or the HIL loop uses another module's private names.

What a module offers is what it names without an underscore
(docs/ARCHITECTURE.md, "Inside the Python side"). The import-graph test
(tests/py/test_architecture.py) refuses `from module import _name`; this
test reads every module's syntax tree for the uses an import does not show:

- `module._name` (or `package.module._name`) on a module of the project;
- `obj._name` on anything but `self` or `cls` when no function, class,
  assignment or attribute of that name is made in the module itself: a
  private attribute or method of an object another module defines (a
  plant's `_host`, say).

The tests' own modules may reach inside what they test; they are not read.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("bench", "hil_sim")
# Underscored names that are public API of the standard library (namedtuple's).
PUBLIC_UNDERSCORED = {"_replace", "_asdict", "_fields", "_make", "_field_defaults"}


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _modules(root: Path) -> dict:
    """{dotted module name: path} of every module of the packages under ``root``."""
    out = {}
    for pkg in PACKAGES:
        for path in sorted((root / pkg).rglob("*.py")):
            parts = list(path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


def _dotted(node) -> str | None:
    """``a.b.c`` for a chain of names and attributes, else None."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        return None
    return ".".join([node.id, *reversed(parts)])


def _made_here(tree) -> set:
    """Every name the module itself defines or assigns, and every attribute it sets."""
    made = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            made.add(node.name)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            made.add(node.attr)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            made.add(node.id)
        elif isinstance(node, ast.arg):
            made.add(node.arg)
    return made


def _module_aliases(tree, modules: dict) -> dict:
    """{local name: module} for the project's modules the module imports."""
    alias = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] in PACKAGES:
                    alias[a.asname or a.name.split(".")[0]] = a.name if a.asname else a.name.split(".")[0]
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in PACKAGES:
            for a in node.names:
                if f"{node.module}.{a.name}" in modules:
                    alias[a.asname or a.name] = f"{node.module}.{a.name}"
    return alias


def private_uses(source: str, modules: dict) -> list:
    """[(line, text)] of the uses of other modules' private names in ``source``."""
    tree = ast.parse(source)
    made, alias = _made_here(tree), _module_aliases(tree, modules)
    bad = []
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Attribute) and _private(node.attr)) or node.attr in PUBLIC_UNDERSCORED:
            continue
        owner = _dotted(node.value)
        if owner is not None:
            head, _, rest = owner.partition(".")
            target = ".".join(x for x in (alias.get(head, head), rest) if x)
            if head in alias and target in modules:
                bad.append((node.lineno, f"{owner}.{node.attr}: a private name of module {target}"))
                continue
            if head in ("self", "cls") and not rest:
                continue
        if node.attr not in made:
            bad.append((node.lineno, f"{ast.unparse(node)}: a private name not made in this module"))
    return sorted(bad)


def test_no_module_uses_another_modules_private_names():
    modules = _modules(ROOT)
    bad = [
        f"{path.relative_to(ROOT)}:{line} {what}"
        for path in modules.values()
        for line, what in private_uses(path.read_text(), modules)
    ]
    assert not bad, "private names used across modules:\n" + "\n".join(bad)


def test_the_check_finds_a_module_attribute_an_object_attribute_and_a_package_path():
    modules = {"bench.sim.plant": None, "bench.sim.vehicle_sim": None, "bench.sim": None, "bench": None}
    source = """
import bench.sim.plant
from bench.sim import plant as pl
from bench.sim.plant import Plant


class Local:
    def __init__(self):
        self._mine = 1

    def same(self, other):
        return other._mine + self._own()


def fly(p: Plant):
    a = pl._host(0.0)
    b = p._host(0.0)
    c = bench.sim.plant._orbit
    d = pl.public(0.0)._replace(x=1)
    return a, b, c, d, Local()._mine
"""
    found = private_uses(source, modules)
    assert [line for line, _ in found] == [16, 17, 18]
    assert "module bench.sim.plant" in found[0][1] and "module bench.sim.plant" in found[2][1]
    assert "not made in this module" in found[1][1]
