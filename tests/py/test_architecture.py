"""The layers of the Python side, checked on its import graph.

The graph is grimp's: every import statement of the bench and hil_sim
packages, the ones inside functions included (a function-local import hides
a cycle from the interpreter, not from a reader). docs/ARCHITECTURE.md
states the rules; each test here fails on the first import that breaks one.
"""
import re

import pytest

grimp = pytest.importorskip("grimp")

# bench/gap, top to bottom: a module may import its own layer or lower ones.
GAP_LAYERS = (
    ("campaigns: blind validation, detection limits, separability, the bundled run",
     {"validate", "validate_vehicle", "validate_basilisk", "validate_mixtures", "perf_diagnose", "results_tables", "bundled",
      "characterise", "separability", "detectable"}),
    ("the answer: verdicts, words, report", {"diagnose", "answers", "report"}),
    ("null calibrations and the flights they simulate",
     {"null", "log_null", "plans", "simlogs"}),
    ("the model: replay, dynamics channel, candidates, screening, selection, detection",
     {"detection", "select", "attribute", "localise", "quantify", "dyn", "candidates", "replay"}),
)
# Only the command line and the HIL performance comparison use the HIL loop;
# the HIL loop builds on the bench's models.
HIL_USERS = re.compile(r"^bench\.(cli|commands(\..*)?|perf_hil)$")


@pytest.fixture(scope="module")
def graph():
    return grimp.build_graph("bench", "hil_sim")


def _edges(graph):
    for m in sorted(graph.modules):
        for t in sorted(graph.find_modules_directly_imported_by(m)):
            yield m, t


def _cycles(graph) -> list:
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    succ = {m: sorted(graph.find_modules_directly_imported_by(m)) for m in graph.modules}

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in succ[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for m in sorted(graph.modules):
        if m not in index:
            visit(m)
    return out


def test_no_import_cycles(graph):
    cycles = _cycles(graph)
    detail = []
    for comp in cycles:
        for a in comp:
            for b in comp:
                for d in graph.get_import_details(importer=a, imported=b):
                    detail.append(f"{a}:{d['line_number']} {d['line_contents']}")
    assert not cycles, "import cycles:\n" + "\n".join(detail)


def test_no_private_names_imported_across_modules(graph):
    bad = []
    for a, b in _edges(graph):
        for d in graph.get_import_details(importer=a, imported=b):
            m = re.match(r"from\s+\S+\s+import\s+(.*)", d["line_contents"])
            names = [n.strip().split(" as ")[0] for n in m.group(1).strip("()").split(",")] if m else []
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            if private:
                bad.append(f"{a}:{d['line_number']} {d['line_contents']}")
    assert not bad, "private names imported from another module:\n" + "\n".join(bad)


def test_hil_loop_is_used_only_by_the_command_line(graph):
    bad = [f"{a} imports {b}" for a, b in _edges(graph)
           if a.startswith("bench") and b.startswith("hil_sim") and not HIL_USERS.match(a)]
    assert not bad, "\n".join(bad)


def test_gap_layers(graph):
    layer_of = {}
    for i, (_, mods) in enumerate(GAP_LAYERS):
        for m in mods:
            layer_of[f"bench.gap.{m}"] = i
    gap = {m for m in graph.modules if m.startswith("bench.gap.")}
    assert gap <= set(layer_of), f"modules of bench/gap in no layer: {sorted(gap - set(layer_of))}"
    bad = []
    for a, b in _edges(graph):
        if a in layer_of and b in layer_of and layer_of[b] < layer_of[a]:
            d = graph.get_import_details(importer=a, imported=b)[0]
            bad.append(f"{a}:{d['line_number']} ({GAP_LAYERS[layer_of[a]][0]}) imports {b} "
                       f"({GAP_LAYERS[layer_of[b]][0]})")
    assert not bad, "\n".join(bad)


def test_the_checks_see_function_local_imports(graph):
    """The graph holds imports made inside functions (the cycle check would
    be blind without them)."""
    details = graph.get_import_details(importer="bench.scenario_docking", imported="bench.image_pose")
    assert details and details[0]["line_contents"].startswith("from bench.image_pose import")
