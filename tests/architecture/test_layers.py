"""The layers of src/bpmcal only call downward (docs/architecture.md): every import in
every module, also one inside a function, names a module of its own layer or of a layer
below. A module that imports upward (e.g. dem/ importing lab/, a stage importing the
report) fails this test."""
import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src" / "bpmcal"

#: the layers, bottom up (docs/architecture.md)
LAYERS = [
    {"bpmcal", "bpmcal.params", "bpmcal.exact_math"},
    {"bpmcal.dem"},
    {"bpmcal.io"},
    {"bpmcal.lab"},
    {"bpmcal.study"},
    {"bpmcal.analysis"},
    {"bpmcal.plots"},
    {"bpmcal.stages"},
    {"bpmcal.report"},
    {"bpmcal.cli"},
]


def layer_of(module: str) -> int:
    """The layer of a module of the package (its package's, or its own for a top module)."""
    parts = module.split(".")
    for depth in (2, 1):
        name = ".".join(parts[:depth])
        for i, layer in enumerate(LAYERS):
            if name in layer:
                return i
    raise KeyError(module)


def module_name(path: Path) -> str:
    rel = path.relative_to(SRC.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module) of every import of the package in a source file."""
    return imports_in(path.read_text(), module_name(path), path.name == "__init__.py")


def _is_module(name: str) -> bool:
    p = SRC.parent / Path(*name.split("."))
    return p.with_suffix(".py").exists() or p.is_dir()


def imports_in(text: str, mod: str, is_package: bool = False) -> list[tuple[int, str]]:
    """(line, absolute module) of every import of the package in ``text``, the source of
    module ``mod``, wherever it stands (also inside functions)."""
    package = mod if is_package else mod.rsplit(".", 1)[0]
    out = []
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names if a.name.startswith("bpmcal")]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.startswith("bpmcal"):
                # "from . import x" / "from .io import layout": the imported names may be modules
                out.append((node.lineno, target))
                out += [(node.lineno, f"{target}.{a.name}") for a in node.names
                        if _is_module(f"{target}.{a.name}")]
    return out


SOURCES = sorted(SRC.rglob("*.py"))


def test_every_module_has_a_layer():
    for f in SOURCES:
        layer_of(module_name(f))


@pytest.mark.parametrize("path", SOURCES, ids=[str(f.relative_to(SRC)) for f in SOURCES])
def test_imports_only_go_down(path):
    me = layer_of(module_name(path))
    up = [f"line {line}: {target} (layer {layer_of(target)} > {me})"
          for line, target in imports(path) if layer_of(target) > me]
    assert not up, f"{path.relative_to(SRC)} imports upward: " + "; ".join(up)


def test_the_check_can_fail():
    """The parser sees relative, absolute and function-level imports: an engine module that
    imported the lab or a stage would be caught."""
    text = "def f():\n    from ..lab import runner\n    import bpmcal.stages.runs\n"
    found = [t for _, t in imports_in(text, "bpmcal.dem.probe")]
    assert "bpmcal.lab.runner" in found and "bpmcal.stages.runs" in found
    assert all(layer_of(t) > layer_of("bpmcal.dem.probe") for t in found)


# ------------------------------------------------------------------------ import cycles
def dependencies_in(text: str, mod: str, is_package: bool = False) -> set[str]:
    """The modules of the package that module ``mod`` (source ``text``) needs loaded,
    wherever its imports stand (also inside functions). ``import a.b`` needs ``a.b``;
    ``from m import n`` needs ``m.n`` when that is a module, and ``m`` itself only when
    some imported name is not a module (an attribute that ``m`` defines or re-exports).
    So ``from . import x`` in a package's ``__init__`` is an edge to its submodule ``x``
    and not to itself, and ``from . import sibling`` in a submodule does not depend on
    the ``__init__``, while ``from . import helper`` (a name defined in ``__init__``)
    does. Parent packages, which Python always initialises first, are not edges."""
    package = mod if is_package else mod.rsplit(".", 1)[0]
    out = set()
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("bpmcal")}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if not target.startswith("bpmcal"):
                continue
            subs = {f"{target}.{a.name}" for a in node.names if _is_module(f"{target}.{a.name}")}
            out |= subs
            if len(subs) < len(node.names):
                out.add(target)
    out.discard(mod)
    return out


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Every strongly connected component of more than one module of ``graph`` (module ->
    the modules it imports; edges to modules outside the graph are ignored), sorted:
    Tarjan's algorithm, iterative."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root] & graph.keys())))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w] & graph.keys()))))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return sorted(out)


def module_graph() -> dict[str, set[str]]:
    return {module_name(f): dependencies_in(f.read_text(), module_name(f), f.name == "__init__.py")
            for f in SOURCES}


def test_no_import_cycle():
    """No module of src/bpmcal imports, directly or through others, a module that imports
    it back: not across packages (the layers) and not within one (e.g. study/config.py and
    study/lab_triaxial.py, which needed a deferred import to load)."""
    found = cycles(module_graph())
    assert not found, "import cycles: " + "; ".join(" <-> ".join(c) for c in found)


def test_the_cycle_check_can_fail():
    """A planted cycle is found, within a package and through three modules; a package's
    ``__init__`` that re-exports its submodules is not a cycle, unless a submodule imports
    a name from the ``__init__`` back."""
    assert cycles({"p.a": {"p.b"}, "p.b": {"p.a"}, "p.c": {"p.a"}}) == [["p.a", "p.b"]]
    assert cycles({"x": {"y"}, "y": {"z"}, "z": {"x"}, "w": set()}) == [["x", "y", "z"]]
    assert cycles({"p.a": {"p.b"}, "p.b": set()}) == []
    init = "from .space import CalibrationSpace\nfrom . import scatter\n"
    deps = dependencies_in(init, "bpmcal.analysis.calibration", is_package=True)
    assert deps == {"bpmcal.analysis.calibration.space", "bpmcal.analysis.calibration.scatter"}
    graph = {"bpmcal.analysis.calibration": deps, "bpmcal.analysis.calibration.space": set(),
             "bpmcal.analysis.calibration.scatter": set()}
    assert cycles(graph) == []
    back = dependencies_in("def f():\n    from . import PAPER_RATIO\n", "bpmcal.analysis.calibration.space")
    assert back == {"bpmcal.analysis.calibration"}
    graph["bpmcal.analysis.calibration.space"] = back
    assert cycles(graph) == [["bpmcal.analysis.calibration", "bpmcal.analysis.calibration.space"]]
    sibling = dependencies_in("from . import fit\n", "bpmcal.analysis.calibration.space")
    assert sibling == {"bpmcal.analysis.calibration.fit"}


def test_the_former_circle_would_be_found():
    """The circle this check was written for: config imported lab_triaxial inside a
    function, lab_triaxial imported config at the top."""
    config = dependencies_in("def _check():\n    from .lab_triaxial import lab_triaxial_problems\n",
                             "bpmcal.study.config")
    triax = dependencies_in("from .config import ConfigError, read_lab\n", "bpmcal.study.lab_triaxial")
    assert cycles({"bpmcal.study.config": config, "bpmcal.study.lab_triaxial": triax}) == [
        ["bpmcal.study.config", "bpmcal.study.lab_triaxial"]]
