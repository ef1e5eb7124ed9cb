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
# The layers are the diagnosis's stages in reverse (bench/gap/diagnose.py
# names them): a stage uses the ones before it, never one after it.
GAP_LAYERS = (
    ("the pipeline, and the test that separates", {"diagnose", "design"}),
    ("9 report", {"report", "report_plots"}),
    ("8 answer", {"answers"}),
    ("7 confirm and select", {"verdict", "select", "alternatives"}),
    (
        "thresholds: the null calibrations, the bundled run",
        {"null", "log_null", "calibration_file", "validity", "bundled"},
    ),
    ("4 detect and map, 6 quantify", {"detection", "localise", "quantify"}),
    ("5 screen: the candidates and their signatures", {"attribute", "candidates"}),
    ("3 channels", {"dyn"}),
    ("2 replay", {"replay"}),
    ("1 load", {"load"}),
)
# Only the command line and the HIL performance comparison use the HIL loop;
# the HIL loop builds on the bench's models.
HIL_USERS = re.compile(r"^bench\.(cli|commands(\..*)?|perf\.perf_hil)$")

# The bench and the HIL loop, top to bottom. A module may import its own
# package and the packages of lower layers; the packages of one layer are
# independent of each other. A module is in the first package its name starts
# with: the gap diagnosis's campaigns sit above it, so they may use the
# diagnosis and the diagnosis never uses them; the other campaigns do not
# know either.
PACKAGE_LAYERS = (
    ("the command line", ("bench.cli", "bench.commands")),
    ("performance comparisons", ("bench.perf",)),
    ("the campaigns that validate the gap diagnosis", ("bench.campaigns.gap",)),
    ("campaigns, the gap diagnosis, the HIL loop", ("bench.campaigns", "bench.gap", "hil_sim")),
    ("simulation models", ("bench.sim",)),
    ("shared: rotations, report files, the campaign runner", ("bench.so3", "bench.report", "bench.runner")),
)
# Modules in no layer: the package itself.
UNLAYERED = {"bench"}
# Imports against the layers, each with why it stays for now; the test fails
# when one of them is gone, so the list only shrinks.
LAYER_EXCEPTIONS: set = set()


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
    bad = [
        f"{a} imports {b}"
        for a, b in _edges(graph)
        if a.startswith("bench") and b.startswith("hil_sim") and not HIL_USERS.match(a)
    ]
    assert not bad, "\n".join(bad)


def _package_of(module: str):
    """(layer index, package) of a module, or None when it is in no layer."""
    for i, (_, packages) in enumerate(PACKAGE_LAYERS):
        for p in packages:
            if module == p or module.startswith(p + "."):
                return i, p
    return None


def _layer_violations(graph) -> set:
    bad = set()
    for a, b in _edges(graph):
        pa, pb = _package_of(a), _package_of(b)
        if pa is None or pb is None or pa[1] == pb[1]:
            continue
        if pb[0] <= pa[0]:  # a higher layer, or a peer of the same layer
            bad.add((a, b))
    return bad


def test_every_module_is_in_a_layer(graph):
    stray = sorted(m for m in graph.modules if _package_of(m) is None and m not in UNLAYERED)
    assert not stray, f"modules in no layer of PACKAGE_LAYERS: {stray}"


def test_package_layers(graph):
    found = _layer_violations(graph)
    bad = []
    for a, b in sorted(found - LAYER_EXCEPTIONS):
        d = graph.get_import_details(importer=a, imported=b)[0]
        la, lb = PACKAGE_LAYERS[_package_of(a)[0]][0], PACKAGE_LAYERS[_package_of(b)[0]][0]
        bad.append(f"{a}:{d['line_number']} ({la}) imports {b} ({lb})")
    assert not bad, "imports against the layers:\n" + "\n".join(bad)
    gone = sorted(LAYER_EXCEPTIONS - found)
    assert not gone, f"no longer imported, remove from LAYER_EXCEPTIONS: {gone}"


def test_layer_check_finds_an_upward_import():
    """The check itself: a model importing a campaign, a campaign importing
    its peer the gap diagnosis, and the diagnosis importing its own
    validation are reported; the validation using the diagnosis is not."""
    g = grimp.ImportGraph()
    for m in (
        "bench.sim.plant",
        "bench.campaigns.nav_campaign",
        "bench.gap.diagnose",
        "bench.campaigns.gap.validate",
        "bench.so3",
    ):
        g.add_module(m)
    g.add_import(importer="bench.sim.plant", imported="bench.campaigns.nav_campaign")
    g.add_import(importer="bench.campaigns.nav_campaign", imported="bench.gap.diagnose")
    g.add_import(importer="bench.campaigns.nav_campaign", imported="bench.so3")
    g.add_import(importer="bench.campaigns.gap.validate", imported="bench.gap.diagnose")
    g.add_import(importer="bench.gap.diagnose", imported="bench.campaigns.gap.validate")
    assert _layer_violations(g) == {
        ("bench.sim.plant", "bench.campaigns.nav_campaign"),
        ("bench.campaigns.nav_campaign", "bench.gap.diagnose"),
        ("bench.gap.diagnose", "bench.campaigns.gap.validate"),
    }


def test_only_the_command_line_and_the_timings_use_the_diagnosis_campaigns(graph):
    """The campaigns that validate the diagnosis are used by the command line
    (``proxops validate-gap``, ``proxops simulate --clocks as-real-logs``)
    and the performance comparisons only: nothing of the product, the models
    or the other campaigns imports them."""
    users = re.compile(r"^bench\.(cli|commands(\..*)?|perf(\..*)?|campaigns\.gap(\..*)?)$")
    bad = [f"{a} imports {b}" for a, b in _edges(graph) if b.startswith("bench.campaigns.gap") and not users.match(a)]
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
            bad.append(
                f"{a}:{d['line_number']} ({GAP_LAYERS[layer_of[a]][0]}) imports {b} ({GAP_LAYERS[layer_of[b]][0]})"
            )
    assert not bad, "\n".join(bad)


def test_the_checks_see_function_local_imports(graph):
    """The graph holds imports made inside functions (the cycle check would
    be blind without them)."""
    details = graph.get_import_details(importer="bench.sim.scenario_docking", imported="bench.sim.image_pose")
    assert details and details[0]["line_contents"].startswith("from bench.sim.image_pose import")
